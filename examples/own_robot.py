"""Plan for your own robot from Python: a URDF among obstacles, start to goal; the trajectory written as JSON.

Run from the repository's root: `python examples/own_robot.py` (writes out/motion.json). Put in your own files and
joint values.
"""

from pathlib import Path

import app

# The robot: URDF or SDF (package:// URIs: package_path=["NAME=DIR"]); obstacles: meshes, SDF or URDF files.
scene = app.build_scene(app.CustomSpec(robot="robots/planar_arm_3.urdf", env=["scenes/bar_obstacles.sdf"]))
print("joints:", scene.coordinate_names)  # start and goal: one value per joint, in this order
oracle = app.CollisionOracle(scene)  # self-collision counts (unless CustomSpec(collisions="environment"))
settings = app.PlanSettings(seed=0)  # budget: 200k collision checks and at most 600 s, unless budget=app.Budget(...)
result = app.plan(oracle, settings, start=[20, 80, -1.57, 0, 0], goal=[80, 80, -1.57, 0, 0])
print(f"{len(result.path)} waypoints, {result.trajectory.duration:.1f} s of motion")
Path("out").mkdir(exist_ok=True)  # out/ is ignored by git
result.trajectory_file().write("out/motion.json")  # joint names, times, positions, velocities, accelerations
