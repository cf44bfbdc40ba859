"""The files a scene is made of: where the shipped ones are (the packages `npp_robots` and `npp_scenes` every parser
knows), which model and mesh formats are read, the largest number taken from any of them, and the methods a mesh
may be decomposed by (app.scene.meshes.decomposition)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENES_DIR = ROOT / "scenes"
PACKAGES = {"npp_robots": ROOT / "robots", "npp_scenes": SCENES_DIR}

MODEL_SUFFIXES = {".urdf", ".sdf"}  # a robot or an environment model
DRAKE_MESH_SUFFIXES = {".obj", ".vtk", ".gltf"}  # meshes Drake reads for collision
CONVERTIBLE_SUFFIXES = {".stl", ".dae", ".ply", ".off", ".glb"}  # converted to .obj for Drake
MESH_SUFFIXES = DRAKE_MESH_SUFFIXES | CONVERTIBLE_SUFFIXES

# The largest mesh coordinate taken (metres, after COLLADA's unit): far beyond any robot or building, far below where
# doubles lose the millimetres (at 1e6 m their spacing is 1e-10 m) and trimesh's vertex merging overflows.
MAX_COORDINATE = 1e6
# The largest number taken from a model file or the inputs for a joint limit or speed (m or rad, per s for speeds), a
# mimic multiplier or offset, an offset, a size or a bound (m): as MAX_COORDINATE, far beyond any robot or building (a
# revolute joint allowed 1e6 rad turns 160,000 times) and far below where the planner's differences and sums overflow
# (joint limits of +-1e300 made the bounds' diagonal infinite) or doubles lose the millimetres.
MAX_MODEL_NUMBER = MAX_COORDINATE
# How a spec may ask for meshes to be made convex pieces (`auto`: a method per connected part).
MESH_METHODS = ("auto", "convex", "shell", "coacd", "faces")
