"""The bad-input table: arguments a user may type wrong, each with the exit code and a fragment of the one line on
stderr it must get, before any work and with nothing written. tests/test_bad_input.py runs every row in-process;
`bench audit` runs them as `python -m app` processes, timed, and reports each one's exit code, first stderr line and
the files it wrote (`run_case`).

Rows hold placeholders for files `prepare` makes in a folder, which is the working directory of the run, so a default
output path (bench --store out/...) written by mistake is seen too: {file} an existing file, {dir} an existing
folder, {out} an empty folder, {long} a path in {out} whose file name is longer than a filesystem allows, {foreign} a
folder of someone else's files, {other_db} another program's SQLite database; scene files {nan_weights} (a NaN
weight), {inverted_box} (a passage box with lo > hi), {negative_velocity}, {zero_acceleration} (limits), {huge_step}
(a step longer than the diagonal) and {big_scene} (a list past the size limit); meshes {stl} (garbage), {cube_mesh}
(a cube), {nan_mesh} (a NaN vertex), {flat_mesh} (collinear vertices) and {huge_mesh} (1e30 coordinates);
trajectories {maze_motion} (of scene maze) and {renamed_motion} (its last joint renamed); roadmap files (a roadmap of
bar's shape with a made-up fingerprint, each damaged one way: app.bench.damaged_roadmaps) {flipped_roadmap} (a member's
compressed data damaged), {crc_roadmap} (a member's checksum wrong), {bomb_roadmap} (a member declaring 4 GB),
{huge_rows_roadmap} (an npy header claiming 10^12 nodes), {negative_k_roadmap} (k = -5) and {fifo} (a named pipe);
ROS 2 bag folders {broken_bag} (metadata no bag has) and {fifo_bag} (a named pipe for its data).
One-joint URDF robots: {huge_limits} (limits +-1e300), {nan_limit}, {inverted_limits} (lower above upper: Drake's
parser would stop the process), {two_mimics} (two <mimic> in one joint), {huge_origin} (a link offset of 1e300 m)
and {stuck_joint} (lower = upper); OMPL.app problems {huge_volume} (volume bounds +-1e308) and {repeated_key} (a
[problem] key given twice).

Paths that cannot be written are a file used as a folder, a folder used as a file, /proc and /sys and over-long names:
the tests run as root in CI, where a write-protected folder stays writable.
"""

from __future__ import annotations

import json
import os
import re
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from app.bench.damaged_roadmaps import invalid_deflate, npy_claiming, patch_member, roadmap_file
from app.io import INPUT_LIMITS
from app.scene.files import ROOT, SCENES_DIR
from app.scene.offline import offline_drake_cache

ROBOT = ["--robot", "{stl}", "--start", "0,0,0,0,0,0", "--goal", "1,0,0,0,0,0", "--bounds", "-1..1,-1..1,-1..1"]
MESH_ROBOT = ["--start", "5,5,5,0,0,0", "--goal", "6,6,6,0,0,0", "--bounds", "0..10,0..10,0..10"]
URDF_ROBOT = ["--start", "0", "--goal", "0.5"]
# What no message may name: the files generated in the cache (problem files, model directives, cached entries).
NO_INTERNAL_FILE = r"problem-[0-9a-f]+\.yaml|(robot|scene)\.dmd\.yaml|/meshes/[0-9a-f]{32}/|/models/[0-9a-f]{24}/"
TOO_LONG = "File name too long"

ROWS = [
    # -- output paths, refused before any work ---------------------------------------------------------------------
    (["plan", "bar", "--out", "{file}/t.json"], 2, "is a file, not a folder"),
    (["plan", "bar", "--out", "{dir}"], 2, "it is a folder"),
    (["plan", "bar", "--out", "/proc/t.json"], 2, "/proc is a system folder"),
    (["plan", "bar", "--out", "{out}/missing/t.json"], 2, "does not exist"),
    (["plan", "bar", "--out", "{out}/t.json", "--html", "{file}/x.html"], 2, "is a file, not a folder"),
    (["plan", "bar", "--out", "{out}/t.json", "--html", "{out}/t.json"], 2, "are the same file"),
    (["plan", "bar", "--html", "{out}/bar.html"], 2, "Meshcat is disabled by DRAKE_ALLOW_NETWORK"),
    (["run", "window", "--out", "{dir}"], 2, "it is a folder"),
    (["run", "window", "--html", "/sys/x.html"], 2, "/sys is a system folder"),
    (["sample", "bar", "--sampler", "lfbs", "--png", "{file}/x.png"], 2, "is a file, not a folder"),
    (["sample", "bar", "--sampler", "lfbs", "--png", "/proc/x.png"], 2, "/proc is a system folder"),
    (["show", "bar", "--png", "{dir}"], 2, "it is a folder"),
    (["view", "bar", "--trajectory", "{file}", "--html", "{file}/x.html"], 2, "is a file, not a folder"),
    (["bench", "plan", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "plan", "--store", "{file}/x.sqlite"], 2, "is a file, not a folder"),
    (["bench", "uav", "--store", "/proc/u.sqlite"], 2, "/proc is a system folder"),
    (["bench", "uav", "--store", "{file}"], 2, "as a results store: it is not a SQLite file"),
    (["bench", "jobs", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "ompl", "--png", "{dir}"], 2, "it is a folder"),
    (["bench", "ompl", "--png", "{out}/o.png", "--store", "{out}/o.png"], 2, "are the same file"),
    (["bench", "sampling", "--png", "{file}/s.png"], 2, "is a file, not a folder"),
    (["bench", "paper", "--out", "{file}"], 2, "is a file, not a folder"),
    (["bench", "paper", "--out", "/proc/paper", "--report-only"], 2, "/proc is a system folder"),
    # -- counts: whole numbers within limits the message names -----------------------------------------------------
    (["run", "window", "--seed", "-1"], 2, "argument --seed: must be from 0 to 4294967295, got -1"),
    (["plan", "bar", "--seed", "99999999999"], 2, "argument --seed: must be from 0 to"),
    (["plan", "bar", "--narrow", "1e9"], 2, "argument --narrow: not a whole number"),
    (["plan", "bar", "--narrow", "1000000000"], 2, "argument --narrow: must be from 0 to 100000"),
    (["plan", "bar", "--uniform", "-5"], 2, "argument --uniform: must be from 0 to 100000"),
    (["plan", "bar", "-k", "1e9"], 2, "argument -k/--neighbours: not a whole number"),
    (["plan", "bar", "-k", "5000"], 2, "argument -k/--neighbours: must be from 1 to 1000"),
    (["plan", "bar", "--smooth", "100000"], 2, "argument --smooth: must be from 0 to 10000"),
    (["run", "window", "--narrow", "200000"], 2, "argument --narrow: must be from 0 to 100000"),
    (["sample", "bar", "--sampler", "lfbs", "-k", "0"], 2, "argument -k: must be from 1 to 100000"),
    (["sample", "bar", "--sampler", "lfbs", "--threads", "0"], 2, "argument --threads: must be from 1 to 256"),
    (["bench", "paper", "--workers", "-1"], 2, "argument --workers: must be from 0 to 256"),
    (["bench", "paper", "--trials", "0"], 2, "argument --trials: must be from 1 to 10000"),
    (["bench", "paper", "--max-checks", "0"], 2, "argument --max-checks: must be from 1 to"),
    (["bench", "plan", "--workers", "1000"], 2, "argument --workers: must be from 1 to 256"),
    (["bench", "plan", "--seeds", "0"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "plan", "-k", "0"], 2, "argument -k/--neighbours: must be from 1 to 1000"),
    (["bench", "uav", "--seeds", "1000000"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "jobs", "--seeds", "-2"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "ompl", "--workers", "0"], 2, "argument --workers: must be from 1 to 256"),
    (["bench", "oracle", "-n", "0"], 2, "argument -n: must be from 1 to"),
    (["bench", "oracle", "--repeats", "100000"], 2, "argument --repeats: must be from 1 to 10000"),
    (["bench", "oracle", "--seed", "-3"], 2, "argument --seed: must be from 0 to"),
    (["bench", "sampling", "--trials", "0"], 2, "argument --trials: must be from 1 to 10000"),
    # -- numbers that are not finite, or out of range --------------------------------------------------------------
    (["plan", "bar", "--resolution", "inf"], 2, "argument --resolution: must be a finite number, got inf"),
    (["plan", "bar", "--mesh-tolerance", "nan"], 2, "argument --mesh-tolerance: must be a finite number"),
    (["plan", "bar", "--mesh-tolerance", "-1"], 2, "argument --mesh-tolerance: must not be negative"),
    (["plan", "bar", "--step", "nan"], 2, "argument --step: must be a finite number"),
    (["plan", "bar", "--step", "-1"], 2, "argument --step: must be a positive finite number"),
    (["plan", "bar", "--dt", "0"], 2, "argument --dt: must be a positive finite number"),
    (["plan", "bar", "--budget", "inf"], 2, "argument --budget: bad budget 'inf'"),
    (["plan", "bar", "--budget", "0s"], 2, "argument --budget: bad budget '0s': must be positive"),
    (["plan", "bar", "--budget", "30s,1min"], 2, "two time limits"),
    (["plan", "bar", "--start", "nan,80,0,0,0,0,0,0,0"], 2, "argument --start: needs finite numbers"),
    (["plan", "bar", "--goal", "1,2,x"], 2, "argument --goal: not a comma-separated list of numbers"),
    (["plan", "bar", "--env-pose", "0,0,0,0,0,inf"], 2, "argument --env-pose: needs finite numbers"),
    (["run", "window", "--budget", "-1s"], 2, "argument --budget: bad budget '-1s'"),
    (["sample", "bar", "--sampler", "lfbs", "--step", "inf"], 2, "argument --step: must be a finite number"),
    (["bench", "sampling", "--steps", "2,inf"], 2, "argument --steps: needs finite numbers"),
    (["bench", "sampling", "--margin", "nan"], 2, "argument --margin: must be a finite number"),
    (["bench", "jobs", "--budget", "nan"], 2, "argument --budget: must be a finite number"),
    (["bench", "ompl", "--budget", "0"], 2, "argument --budget: must be a positive finite number"),
    (["bench", "paper", "--steps", "0,10"], 2, "argument --steps: must be positive numbers"),
    # -- negative values typed as a user would, checked against the scene -------------------------------------------
    (["plan", "bar", "--start", "-1.57,0,0"], 2, "start has 3 values; the robot needs 9"),
    (["plan", "bar", "--goal", "-20,-80,0,0,0,0,0,0,0"], 3, "goal is out of bounds"),
    (["plan", "bar", "--start", "50,30,0,0,0,0,0,0,0"], 3, "start is in collision"),
    # -- names, files and combinations -----------------------------------------------------------------------------
    (["plan", "bar", "--sampler", "magic"], 2, "argument --sampler: unknown sampler 'magic'"),
    (["plan", "nowhere"], 2, "nowhere"),
    (["plan"], 2, "a SCENE (name or file) or --robot is required"),
    (["plan", "bar", *ROBOT], 2, "give either SCENE or --robot/--env, not both"),
    (["plan", "--env", "{stl}"], 2, "--env needs --robot"),
    (["plan", "bar", "--resolution", "0.5"], 2, "--resolution needs --robot"),
    (["plan", "bar", "--no-self-collision", "--mesh-method", "faces"], 2, "--mesh-method, --no-self-collision need"),
    (["plan", "window", "--srdf", "{file}"], 2, "--srdf needs --robot"),
    (["plan", "window", "--goal", "0,0,0,0,0,0,0,0", "--goal-pose", "0.3,0,0.3,0,90,0"], 2, "not both"),
    (["plan", "window", "--tool", "tcp"], 2, "--tool needs --start-pose or --goal-pose"),
    (["plan", "window", "--goal-pose", "0.3,0,0.3"], 2, "--goal-pose"),
    (["plan", "window", "--goal-pose", "5,0,0.3,0,90,0"], 3, "cannot be reached"),
    (["plan", "bar", "--wait", "2"], 2, "--wait needs --meshcat"),
    (["plan", "bar", "--frame", "base"], 2, "--frame needs --html or --meshcat"),
    (["run", "window", "--frame", "tool0"], 2, "--frame needs --html or --meshcat"),
    (["plan", "bar", "--meshcat", "--wait", "-1"], 2, "argument --wait"),
    (["bench", "certify", "--seeds", "0"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "certify", "--scenes", "nowhere"], 2, "argument --scenes"),
    (["bench", "audit", "--problems", "0"], 2, "argument --problems: must be from 1 to 10000"),
    (["bench", "audit", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "audit", "--workers", "1000"], 2, "argument --workers: must be from 1 to 256"),
    (["plan", *ROBOT], 2, "cannot read mesh garbage.stl: not a valid .stl file"),
    (["plan", "--robot", "{out}/none.urdf", "--start", "0", "--goal", "1"], 2, "robot file not found"),
    (["plan", "{nan_weights}"], 2, "'weights' needs finite numbers, item 2 is nan"),
    (["plan", "bar", "--mesh-method", "magic"], 2, "argument --mesh-method: invalid choice"),
    (["run", "painting"], 2, "unknown job 'painting'"),
    (["view", "bar", "--trajectory", "{file}"], 2, "nothing to do"),
    (["view", "bar", "--trajectory", "{out}/none.json", "--html", "{out}/x.html"], 2, "trajectory file not found"),
    (["sample", "bar"], 2, "the following arguments are required: --sampler"),
    (["show", "bar"], 2, "the following arguments are required: --png"),
    (["scenes", "extra"], 2, "unrecognized arguments: extra"),
    (["bench"], 2, "the following arguments are required: kind"),
    (["bench", "plan", "--samplers", "lfbs,magic"], 2, "argument --samplers: unknown sampler 'magic'"),
    (["bench", "jobs", "--jobs", "painting"], 2, "argument --jobs: unknown job 'painting'"),
    (["bench", "paper", "--parts", "everything"], 2, "argument --parts: unknown part 'everything'"),
    (["bench", "ompl", "--methods", "ompl:Magic"], 2, "argument --methods"),
    (["fly"], 2, "invalid choice: 'fly'"),
    # -- output folders of bench paper: never someone else's, and --report-only runs nothing -----------------------
    (["bench", "paper", "--out", "{foreign}", "--parts", "sampling"], 2, "is a folder of other files"),
    (["bench", "paper", "--out", "{foreign}", "--report-only"], 2, "holds no results of bench paper"),
    (["bench", "paper", "--out", "{out}/none", "--report-only"], 2, "holds no results of bench paper"),
    (["bench", "plan", "--store", "{other_db}"], 2, "another program's SQLite database"),
    # -- output paths longer than the filesystem allows, for every command that writes ------------------------------
    (["plan", "bar", "--out", "{long}"], 2, TOO_LONG),
    (["run", "window", "--out", "{long}"], 2, TOO_LONG),
    (["sample", "bar", "--sampler", "lfbs", "--png", "{long}"], 2, TOO_LONG),
    (["show", "bar", "--png", "{long}"], 2, TOO_LONG),
    (["view", "bar", "--trajectory", "{file}", "--html", "{long}"], 2, TOO_LONG),
    (["gui", "bar", "--state", "{long}"], 2, TOO_LONG),
    (["bench", "plan", "--store", "{long}"], 2, TOO_LONG),
    (["bench", "uav", "--store", "{long}"], 2, TOO_LONG),
    (["bench", "jobs", "--store", "{long}"], 2, TOO_LONG),
    (["bench", "certify", "--store", "{long}"], 2, TOO_LONG),
    (["bench", "audit", "--store", "{long}"], 2, TOO_LONG),
    (["bench", "ompl", "--png", "{long}"], 2, TOO_LONG),
    (["bench", "sampling", "--png", "{long}"], 2, TOO_LONG),
    (["bench", "paper", "--out", "{long}"], 2, TOO_LONG),
    (["bench", "paper", "--out", "{out}/paper", "--ompl-db", "{long}"], 2, TOO_LONG),
    (["plan", "bar", "--out", ""], 2, "empty argument after --out"),
    (["plan", "bar", "--robot="], 2, "argument --robot: empty value"),
    (["gui", "--robot", "{out}/none.urdf"], 2, "robot file not found"),
    (["gui", "--robot", "{stl}"], 2, "cannot read mesh garbage.stl"),
    (["bench", "audit", "--store", " "], 2, "empty argument after --store"),
    # -- steps and sample periods that would never end or say nothing -------------------------------------------------
    (["sample", "bar", "--sampler", "lfbs", "--step", "1e308"], 2, "step 1e+308 is longer than the scene's diagonal"),
    (["plan", "bar", "--step", "1e308"], 2, "step 1e+308 is longer than the scene's diagonal"),
    (["bench", "ompl", "--scenes", "bar", "--step", "1e308"], 2, "step 1e+308 is longer than the scene's diagonal"),
    (["bench", "plan", "--scenes", "bar", "--step", "1e308"], 2, "step 1e+308 is longer than the scene's diagonal"),
    (["bench", "paper", "--scenes", "bar", "--steps", "2,1e308"], 2, "step 1e+308 is longer than the scene's"),
    (["bench", "paper", "--scenes", "nowhere"], 2, "unknown scene 'nowhere'"),
    (["plan", "bar", "--dt", "1e308"], 2, "argument --dt: must be at most 1 s"),
    (["plan", "bar", "--budget", "1e308s"], 2, "bad budget '1e308s'"),
    (["plan", "bar", "--budget", "2000000000checks"], 2, "from 1 to 1000000000 checks"),
    (["run", "window", "--budget", "2000min"], 2, "at most 86400 s (a day)"),
    (["bench", "jobs", "--budget", "1e308"], 2, "argument --budget: must be at most 86400 s"),
    (["bench", "ompl", "--budget", "1e6"], 2, "argument --budget: must be at most 86400 s"),
    (["bench", "plan", "--budget", "99999999999999999999"], 2, "argument --budget: must be at most 86400 s"),
    # -- input files: sizes, scene files and meshes refused at load, naming the file ---------------------------------
    (["plan", "{big_scene}"], 2, "big.yaml is too large"),
    (["plan", "{inverted_box}"], 2, "passage box 1 needs finite lo <= hi"),
    (["plan", "{negative_velocity}"], 2, "'velocity_limits' must be positive, item 9"),
    (["plan", "{zero_acceleration}"], 2, "'acceleration_limits' must be positive, item 9"),
    (["sample", "{huge_step}", "--sampler", "rws"], 2, "huge_step.yaml: step 1e+300 is longer than the scene's"),
    (["plan", "--robot", "{flat_mesh}", *MESH_ROBOT], 2, "flat.obj: every triangle has zero area"),
    (["plan", "--robot", "{cube_mesh}", *MESH_ROBOT, "--resolution", "1e9"], 2, "to the diagonal (25.6), got 1e+09"),
    (["plan", "--robot", "{huge_mesh}", *MESH_ROBOT], 2, "huge.obj: coordinates up to 1e+30; the limit is 1e+06"),
    (["plan", "--robot", "{cube_mesh}", "--env", "{nan_mesh}", *MESH_ROBOT], 2, "nan.obj: vertex 8 has a coordinate"),
    (["plan", "--ompl-app", "{out}/missing.cfg"], 2, "OMPL.app problem file not found"),
    (["plan", "--ompl-app", "{dir}"], 2, "is not a file"),
    (["plan", "--ompl-app", "{file}"], 2, "File contains no section headers"),
    (["plan", "--ompl-app", "{huge_volume}"], 2, "huge_volume.cfg: volume.min.x = -1e308 is out of range"),
    (["plan", "--ompl-app", "{repeated_key}"], 2, "repeated_key.cfg: [problem] goal.x is given twice (lines 7 and 14)"),
    # -- a robot's own numbers, refused before any arithmetic, naming the joint and the value ------------------------
    (["plan", "--robot", "{huge_limits}", *URDF_ROBOT], 2, "joint 'slide': lower limit -1e300 is out of range"),
    (["plan", "--robot", "{nan_limit}", *URDF_ROBOT], 2, "nan_limit.urdf: joint 'slide': upper limit nan is not a"),
    (["plan", "--robot", "{inverted_limits}", *URDF_ROBOT], 2, "lower limit 1 is above upper limit -1"),
    (["plan", "--robot", "{two_mimics}", *URDF_ROBOT], 2, "two_mimics.urdf: joint 'slide' has 2 <mimic> elements"),
    (["plan", "--robot", "{huge_origin}", *URDF_ROBOT], 2, "link 'carriage': <origin xyz=\"1e300 0 0\"> is out of"),
    (["plan", "--robot", "{stuck_joint}", *URDF_ROBOT], 2, "stuck_joint.urdf: joint 'slide': lower limit 0"),
    (["plan", "--robot", "{cube_mesh}", *MESH_ROBOT[2:], "--start", "1e300,0,0,0,0,0"], 2, "x is 1e+300"),
    (["plan", "--robot", "{cube_mesh}", "--start", "5,5,5,0,0,0", "--bounds", "-1e308..1e308,0..10,0..10"], 2, "1e308"),
    (["plan", "bar", "--ompl-app", "{file}"], 2, "--ompl-app sets the robot, environment and bounds"),
    (["roadmap", "info", "{file}"], 2, "is not a roadmap file of this planner (not an .npz archive)"),
    (["plan", "bar", "--roadmap", "{file}"], 2, "is not a roadmap file of this planner (not an .npz archive)"),
    (["view", "bar", "--trajectory", "{dir}", "--html", "{out}/x.html"], 2, "is not a ROS 2 bag"),
    (["view", "bar", "--trajectory", "{long}", "--html", "{out}/x.html"], 2, "cannot read trajectory file"),
    (["view", "tunnel", "--trajectory", "{maze_motion}", "--html", "{out}/x.html"], 2, "scene 'maze', not of 'tunnel'"),
    (["view", "maze", "--trajectory", "{renamed_motion}", "--html", "{out}/x.html"], 2, "joint 4 is 'heading'"),
    (["view", "bar", "--trajectory", "{broken_bag}", "--bag", "{out}/b"], 2, "cannot read bag broken_bag"),
    (["view", "bar", "--trajectory", "{fifo_bag}", "--bag", "{out}/b"], 2, "fifo_bag/fifo_bag.db3 is not a file"),
    # -- roadmap files: damaged, hostile or not files at all, refused before anything is planned or written ---------
    (["plan", "bar", "--roadmap", "{fifo}"], 2, "is a named pipe (FIFO), not a file"),
    (["roadmap", "info", "{fifo}"], 2, "is a named pipe (FIFO), not a file"),
    (["roadmap", "info", "{dir}"], 2, "is a folder, not a file"),
    (["roadmap", "info", "/dev/null"], 2, "is a device, not a file"),
    (["plan", "bar", "--roadmap", "{flipped_roadmap}"], 2, "Error -3 while decompressing data"),
    (["roadmap", "info", "{crc_roadmap}"], 2, "Bad CRC-32 for file 'Q.npy'"),
    (["plan", "bar", "--roadmap", "{bomb_roadmap}"], 2, "would unpack to 3.73 GiB, over the 1 GiB limit"),
    (["roadmap", "info", "{huge_rows_roadmap}"], 2, "claims shape (1000000000000, 9)"),
    (["plan", "bar", "--roadmap", "{negative_k_roadmap}"], 2, "its k is -5"),
]


ONE_JOINT = """<?xml version="1.0"?>
<robot name="slider">
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="carriage">
    <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="{origin} 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry></collision>
  </link>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/>{mimic}</joint>
</robot>
"""
OMPL_PROBLEM = """[problem]
robot = cube.obj
world = cube.obj
start.x = 0
start.y = 0
start.theta = 0
goal.x = 5
goal.y = 5
goal.theta = 0
volume.min.x = {lo}
volume.min.y = {lo}
volume.max.x = {hi}
volume.max.y = {hi}
{extra}
[planner]
aps=
aps=
"""


def _one_joint(lower="-1", upper="1", mimic="", origin="0.3") -> str:
    return ONE_JOINT.format(lower=lower, upper=upper, mimic=mimic, origin=origin)


CUBE = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_FACES = [
    (1, 3, 2),
    (2, 3, 4),
    (5, 6, 7),
    (6, 8, 7),
    (1, 2, 5),
    (2, 6, 5),
    (3, 7, 4),
    (4, 7, 8),
    (1, 5, 3),
    (3, 5, 7),
    (2, 4, 6),
    (4, 8, 6),
]


def _obj(vertices, faces) -> str:
    return "".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + "".join(f"f {a} {b} {c}\n" for a, b, c in faces)


def _motion(scene: str, names: list[str]) -> str:
    q = [1.0] * len(names)
    zero = [0.0] * len(names)
    return json.dumps(
        {
            "schema": "npp-trajectory/1",
            "scene": scene,
            "joint_names": names,
            "time_from_start": [0.0],
            "positions": [q],
            "velocities": [zero],
            "accelerations": [zero],
            "waypoints": [q],
            "waypoint_times": [0.0],
            "certified": False,
        }
    )


def prepare(folder: Path) -> dict[str, Path]:
    """The placeholders' files in `folder` (see the module doc); returns the placeholder values."""
    folder = Path(folder)
    (folder / "file").write_text("x")
    for name in ("dir", "out", "foreign"):
        (folder / name).mkdir()
    (folder / "foreign" / "report.md").write_text("someone's notes\n")
    (folder / "garbage.stl").write_bytes(bytes(range(256)) * 2)
    (folder / "bar.dmd.yaml").write_text((SCENES_DIR / "bar.dmd.yaml").read_text())
    bar = (SCENES_DIR / "bar.yaml").read_text()
    scenes = {
        "nan_weights": re.sub(r"(?m)^weights: \[1, 1,", "weights: [1, .nan,", bar),
        "inverted_box": bar.replace("{lo: [45, 46, -1], hi: [55, 54, 1]}", "{lo: [55, 46, -1], hi: [45, 54, 1]}"),
        "negative_velocity": bar + "velocity_limits: [1, 1, 1, 1, 1, 1, 1, 1, -1]\n",
        "zero_acceleration": bar + "acceleration_limits: [1, 1, 1, 1, 1, 1, 1, 1, 0]\n",
        "huge_step": bar + "step: 1e300\n",
    }
    for name, text in scenes.items():
        assert text != bar, name  # the shipped file still has what the edit changes
        (folder / f"{name}.yaml").write_text(text)
    # A list just long enough to pass the limit (the same check refuses a 10^7-element list of 20 MB).
    count = INPUT_LIMITS["scene file"] // 2 + 1
    (folder / "big.yaml").write_text(bar + "weights: [" + ",".join(["1"] * count) + "]\n")
    (folder / "cube.obj").write_text(_obj(CUBE, CUBE_FACES))
    (folder / "nan.obj").write_text(_obj(CUBE[:7] + [("nan", 1, 1)], CUBE_FACES))
    (folder / "flat.obj").write_text(_obj([(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)], [(1, 2, 3), (2, 3, 4)]))
    (folder / "huge.obj").write_text(
        _obj([(0, 0, 0), (1e30, 0, 0), (0, 1e30, 0), (0, 0, 1e30)], [(1, 2, 3), (1, 3, 4), (1, 2, 4), (2, 3, 4)])
    )
    robots = {
        "huge_limits": _one_joint(lower="-1e300", upper="1e300"),
        "nan_limit": _one_joint(upper="nan"),
        "inverted_limits": _one_joint(lower="1", upper="-1"),
        "two_mimics": _one_joint(mimic='<mimic joint="slide"/><mimic joint="slide" multiplier="2"/>'),
        "huge_origin": _one_joint(origin="1e300"),
        "stuck_joint": _one_joint(lower="0", upper="0"),
    }
    for name, text in robots.items():
        (folder / f"{name}.urdf").write_text(text)
    (folder / "huge_volume.cfg").write_text(OMPL_PROBLEM.format(lo="-1e308", hi="1e308", extra=""))
    (folder / "repeated_key.cfg").write_text(OMPL_PROBLEM.format(lo="-10", hi="10", extra="goal.x = 6\n"))
    (folder / "maze_motion.json").write_text(_motion("maze", ["x", "y", "z", "yaw"]))
    (folder / "renamed_motion.json").write_text(_motion("maze", ["x", "y", "z", "heading"]))
    os.mkfifo(folder / "pipe.npz")
    for name in ("broken_bag", "fifo_bag"):  # ROS 2 bag folders: metadata that is no bag's; a named pipe as its data
        (folder / name).mkdir()
    (folder / "broken_bag" / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 8\n")
    (folder / "fifo_bag" / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 8\n")
    os.mkfifo(folder / "fifo_bag" / "fifo_bag.db3")
    good = roadmap_file()
    (folder / "flipped.npz").write_bytes(invalid_deflate(good, "Q.npy"))
    (folder / "crc.npz").write_bytes(patch_member(good, "Q.npy", crc=0))
    (folder / "bomb.npz").write_bytes(patch_member(good, "Q.npy", file_size=4_000_000_000))
    (folder / "huge_rows.npz").write_bytes(roadmap_file(Q=npy_claiming((10**12, 9), "<f8", b"\0" * 720)))
    (folder / "negative_k.npz").write_bytes(roadmap_file(k=-5))
    db = sqlite3.connect(folder / "other.sqlite")
    db.execute("CREATE TABLE notes (text TEXT)")
    db.commit()
    db.close()
    return places(folder)


# Placeholder -> its file's name in the folder.
_FILES = {
    "file": "file",
    "dir": "dir",
    "out": "out",
    "foreign": "foreign",
    "stl": "garbage.stl",
    "nan_weights": "nan_weights.yaml",
    "inverted_box": "inverted_box.yaml",
    "negative_velocity": "negative_velocity.yaml",
    "zero_acceleration": "zero_acceleration.yaml",
    "huge_step": "huge_step.yaml",
    "big_scene": "big.yaml",
    "cube_mesh": "cube.obj",
    "nan_mesh": "nan.obj",
    "flat_mesh": "flat.obj",
    "huge_mesh": "huge.obj",
    "huge_limits": "huge_limits.urdf",
    "nan_limit": "nan_limit.urdf",
    "inverted_limits": "inverted_limits.urdf",
    "two_mimics": "two_mimics.urdf",
    "huge_origin": "huge_origin.urdf",
    "stuck_joint": "stuck_joint.urdf",
    "huge_volume": "huge_volume.cfg",
    "repeated_key": "repeated_key.cfg",
    "maze_motion": "maze_motion.json",
    "renamed_motion": "renamed_motion.json",
    "other_db": "other.sqlite",
    "long": "out/" + "a" * 300 + ".json",
    "fifo": "pipe.npz",
    "broken_bag": "broken_bag",
    "fifo_bag": "fifo_bag",
    "flipped_roadmap": "flipped.npz",
    "crc_roadmap": "crc.npz",
    "bomb_roadmap": "bomb.npz",
    "huge_rows_roadmap": "huge_rows.npz",
    "negative_k_roadmap": "negative_k.npz",
}


def places(folder: Path) -> dict[str, Path]:
    """The placeholder values for a folder made by `prepare`."""
    return {name: Path(folder) / file for name, file in _FILES.items()}


def arguments(argv: list[str], places: dict) -> list[str]:
    """A row's arguments with its placeholders filled in."""
    return [a.format(**places) for a in argv]


def files(folder: Path) -> dict[str, tuple[int, int] | None]:
    """Every file and folder under `folder`: relative path -> a file's size and modification time (None for a
    folder, whose time changes with its files), to see what a run wrote, changed or removed."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) if p.is_file() else None
        for p in Path(folder).rglob("*")
    }


def run_case(argv: list[str], timeout: float = 60.0) -> dict:
    """One row as `python -m app`, in a fresh folder made by `prepare` (its working directory), offline as the tests
    run (DRAKE_ALLOW_NETWORK=none, caches of its own): the exit code (None when it ran past `timeout` seconds and was
    killed), the first stderr line, whether stderr held a traceback, the seconds it took, and the files it wrote,
    changed or removed in its folder."""
    with tempfile.TemporaryDirectory(prefix="npp-bad-input-") as tmp:
        folder = Path(tmp) / "work"
        folder.mkdir()
        values = prepare(folder)
        cache = offline_drake_cache(Path(tmp) / "cache")
        before = files(folder)
        started = time.perf_counter()
        env = {
            **os.environ,
            "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
            "DRAKE_ALLOW_NETWORK": "none",
            "XDG_CACHE_HOME": str(cache),
            "NPP_CACHE_DIR": str(cache / "npp"),
            "NPP_KEY_FILE": str(Path(tmp) / "cache.key"),
            "MPLBACKEND": "Agg",
        }
        try:
            done = subprocess.run(
                [sys.executable, "-m", "app", *arguments(argv, values)],
                cwd=folder,
                capture_output=True,
                text=True,
                timeout=timeout,
                stdin=subprocess.DEVNULL,
                env=env,
            )
            code, stderr = done.returncode, done.stderr
        except subprocess.TimeoutExpired as exc:
            code, stderr = None, exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else ""
        seconds = time.perf_counter() - started
        after = files(folder)
    written = sorted(name for name in after.keys() ^ before.keys() | {n for n in after if after[n] != before.get(n)})
    lines = stderr.strip().splitlines()
    return {
        "exit_code": code,
        "first_line": lines[0] if lines else "",
        "stderr_lines": len(lines),
        "traceback": "Traceback" in stderr,
        "seconds": seconds,
        "written": written,
    }
