"""The scene stage: a robot and its environment as a Drake model, and the configuration space they define.

`model` (shipped scenes: model directives plus a problem file), `custom` (a user's URDF/SDF and mesh environment),
`meshes` (mesh conversion and convex decomposition), `cspace` (bounds, metric, interpolation; numpy only).
"""
