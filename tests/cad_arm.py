"""A UR-like six-joint arm written the way CAD tools export one (no files shipped): per link an STL with every
triangle's corners stored anew (as STL does), several overlapping shells (housings, tubes, flanges) whose faces are
tessellated apart and not stitched (open parts; the chamfers' facets are 2-face slivers: 99-318 parts per link),
and on the upper arm a closed, non-convex bracket. Joints as a UR3's (shoulder pan z, lift y, elbow y, wrist 1 y,
wrist 2 z, wrist 3 y).

How long it loads is measured by a benchmark, not asserted by a test: `python tests/cad_arm.py DIR` writes the arm
with a post round which to plan (`write_cell`) and prints the `bench oracle` command that loads it into an empty mesh
cache and again from the cache ("load s (first/cached)"), and measures its collision checks."""

import sys
from pathlib import Path

import numpy as np
import trimesh

from mesh_shapes import extrude_x

LINKS = ("base", "shoulder", "upper_arm", "forearm", "wrist1", "wrist2", "wrist3")
JOINTS = [  # name, parent, child, origin xyz, axis
    ("shoulder_pan", "base", "shoulder", "0 0 0.09", "0 0 1"),
    ("shoulder_lift", "shoulder", "upper_arm", "0 0.06 0.06", "0 1 0"),
    ("elbow", "upper_arm", "forearm", "0 -0.05 0.24", "0 1 0"),
    ("wrist1", "forearm", "wrist1", "0 0 0.21", "0 1 0"),
    ("wrist2", "wrist1", "wrist2", "0 0.05 0.04", "0 0 1"),
    ("wrist3", "wrist2", "wrist3", "0 0.04 0.05", "0 1 0"),
]
ADJACENT = [(parent, child) for _, parent, child, *_ in JOINTS]
T = trimesh.transformations.translation_matrix
R = trimesh.transformations.rotation_matrix


def _cylinder(radius, height, axis="z", at=(0, 0, 0), sections=48, chamfer=0.001):
    """A chamfered cylinder as a CAD exporter tessellates it: each B-rep face on its own, unstitched: the side (one
    open band), both caps (discs with their own, finer tessellation: their rims do not share the band's vertices)
    and the chamfers, whose every 2-triangle facet is a face of its own (the 2-face slivers), 1 um apart."""
    rotate = {"z": np.eye(4), "y": R(-np.pi / 2, [1, 0, 0]), "x": R(np.pi / 2, [0, 1, 0])}[axis]
    h, r, c = height / 2, radius, chamfer
    angles = np.linspace(0, 2 * np.pi, sections, endpoint=False)
    ring = np.c_[np.cos(angles), np.sin(angles)]
    band = np.vstack([np.c_[r * ring, np.full(sections, -h + c)], np.c_[r * ring, np.full(sections, h - c)]])
    k = np.arange(sections)
    band_faces = np.r_[np.c_[k, (k + 1) % sections, sections + (k + 1) % sections],
                       np.c_[k, sections + (k + 1) % sections, sections + k]]  # fmt: skip
    parts = [trimesh.Trimesh(band, band_faces, process=False)]
    for sign in (-1, 1):
        fine = np.linspace(0, 2 * np.pi, sections + 16, endpoint=False)
        disc = np.vstack(
            [[0, 0, sign * h], np.c_[(r - c) * np.cos(fine), (r - c) * np.sin(fine), np.full(len(fine), sign * h)]]
        )
        m = np.arange(len(fine))
        fan = np.c_[np.zeros(len(fine), int), 1 + m, 1 + (m + 1) % len(fine)]
        parts.append(trimesh.Trimesh(disc, fan if sign > 0 else fan[:, ::-1], process=False))
        gap = 1e-6
        for a, b in zip(angles, np.roll(angles, -1)):
            b = b if b > a else b + 2 * np.pi
            a, b = a + gap / r, b - gap / r  # unstitched from the neighbouring facets
            corners = [(r, a, h - c), (r, b, h - c), (r - c, b, h), (r - c, a, h)]
            quad = np.array([(rho * np.cos(t), rho * np.sin(t), sign * z) for rho, t, z in corners])
            faces = [[0, 1, 2], [0, 2, 3]] if sign > 0 else [[0, 2, 1], [0, 3, 2]]
            parts.append(trimesh.Trimesh(quad, faces, process=False))
    mesh = trimesh.util.concatenate(parts)
    mesh.apply_transform(T(at) @ rotate)
    return mesh


def _bracket(at):
    """A closed U-shaped clevis (non-convex): 0.06 long in x, 0.05 wide, 0.02 high, a 0.03-wide slot open to +z."""
    section = np.array(
        [(-0.025, -0.01), (0.025, -0.01), (0.025, 0.01), (0.015, 0.01), (0.015, -0.005), (-0.015, -0.005),
         (-0.015, 0.01), (-0.025, 0.01)]
    )  # fmt: skip
    mesh = extrude_x(section, 0.06)
    mesh.apply_translation(at)
    return mesh


def link_shells(name: str) -> list[trimesh.Trimesh]:
    """The shells of a link in its frame, overlapping: chamfered cylinders (open parts, see `_cylinder`) and, on the
    upper arm, a closed bracket."""
    if name == "base":
        return [_cylinder(0.045, 0.08, at=(0, 0, 0.04)), _cylinder(0.06, 0.01, at=(0, 0, 0.005))]
    if name == "shoulder":
        return [_cylinder(0.045, 0.09, at=(0, 0, 0.03)), _cylinder(0.045, 0.07, "y", at=(0, 0.035, 0.06))]
    if name == "upper_arm":
        return [
            _cylinder(0.045, 0.1, "y", at=(0, 0.02, 0)),
            _cylinder(0.03, 0.2, at=(0, 0, 0.12)),
            _cylinder(0.04, 0.09, "y", at=(0, -0.005, 0.24)),
            _bracket((0.03, 0, 0.12)),
        ]
    if name == "forearm":
        return [_cylinder(0.035, 0.08, "y", at=(0, 0, 0)), _cylinder(0.025, 0.18, at=(0, 0, 0.1))]
    if name == "wrist1":
        return [_cylinder(0.032, 0.08, "y", at=(0, 0.02, 0)), _cylinder(0.032, 0.06, at=(0, 0.05, 0.02))]
    if name == "wrist2":
        return [_cylinder(0.032, 0.07, at=(0, 0, 0.02)), _cylinder(0.032, 0.07, "y", at=(0, 0.03, 0.05))]
    return [_cylinder(0.03, 0.03, "y", at=(0, 0.015, 0))]


def link_mesh(name: str) -> trimesh.Trimesh:
    """The link as a CAD STL holds it: its shells' faces as one triangle soup."""
    return trimesh.util.concatenate(link_shells(name))


def write_stl(mesh: trimesh.Trimesh, path) -> None:
    """Binary STL: three float32 corners per triangle, each shared corner written again (no vertex list)."""
    path.write_bytes(trimesh.exchange.stl.export_stl(mesh))


def urdf(mesh_dir: str = "meshes") -> str:
    inertial = (
        '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    out = ['<?xml version="1.0"?>', '<robot name="cad_arm">']
    for name in LINKS:
        geometry = f'<geometry><mesh filename="{mesh_dir}/{name}.stl"/></geometry>'
        out.append(
            f'  <link name="{name}">{inertial}<visual>{geometry}</visual><collision>{geometry}</collision></link>'
        )
    for name, parent, child, xyz, axis in JOINTS:
        out.append(
            f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/>'
            "</joint>"
        )
    return "\n".join(out + ["</robot>", ""])


def srdf(pairs) -> str:
    lines = ['<?xml version="1.0"?>', '<robot name="cad_arm">']
    lines += [f'  <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>' for a, b in pairs]
    return "\n".join(lines + ["</robot>", ""])


def write_arm(folder) -> None:
    """cad_arm.urdf, cad_arm.srdf (adjacent pairs) and meshes/<link>.stl in `folder`."""
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    for name in LINKS:
        write_stl(link_mesh(name), folder / "meshes" / f"{name}.stl")
    (folder / "cad_arm.urdf").write_text(urdf())
    (folder / "cad_arm.srdf").write_text(srdf(ADJACENT))


# Start and goal of a plan round the post: the arm reaching out left of it; the straight way (pan 0) runs into it.
START = [-0.9, 0.9, 0.6, 0, 0, 0]
GOAL = [0.9, 0.9, 0.6, 0, 0, 0]


def write_post(path) -> None:
    """A 5 x 5 x 60 cm post beside the arm's base, on a 60 x 60 cm floor plate under it, as one STL."""
    post = trimesh.creation.box([0.05, 0.05, 0.6], T([0.3, 0, 0.3]))
    floor = trimesh.creation.box([0.6, 0.6, 0.02], T([0, 0, -0.011]))
    trimesh.util.concatenate([post, floor]).export(path)


def write_cell(folder) -> Path:
    """The arm (write_arm), the post (post.stl) and a custom scene file naming them with a start and goal round the
    post (cad_arm.yaml, which `plan` and `bench oracle` take); returns the scene file's path."""
    folder = Path(folder)
    write_arm(folder)
    write_post(folder / "post.stl")
    scene = folder / "cad_arm.yaml"
    scene.write_text(
        "description: a UR-like arm exported as CAD tools export one, beside a post (tests/cad_arm.py)\n"
        f"robot: cad_arm.urdf\nsrdf: cad_arm.srdf\nenv: [post.stl]\nstart: {START}\ngoal: {GOAL}\n"
    )
    return scene


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/cad_arm.py DIR  (writes the CAD arm's scene into DIR)")
    written = write_cell(Path(sys.argv[1]))
    print(f"wrote {written}; its load times (into an empty mesh cache, then from it) and check costs:")
    print(f"  python -m app bench oracle --scenes {written}")
