"""The scene stage: a robot and its environment as a Drake model, and the configuration space they define.

A scene is built in stages, each a module that imports only the stages before it (pyproject.toml's contract):
(a) the inputs read as plain data and checked: `problem` (a shipped scene's problem file), `inputs` and `spec` (a
custom scene's keys and files), `model_files` (a URDF/SDF/SRDF read as data); (b) `prepare_meshes` over `meshes`
(mesh conversion, convex decomposition, validation, cache); (c) `emit` (the model files, directives and problem file
Drake parses); (d) `build` (the Drake diagram, its collision filters; the robot alone, measured); (e) `coordinates`
(bounds, weights, continuous joints, the edge-check step; numpy only). `model.Scene` holds the result; `custom`
(a user's URDF/SDF and meshes) and `ompl_app` (an OMPL.app problem) are the routes through the stages. Beneath them:
`drake_parser` (Drake's parser on one file), `files` (where the shipped files are, which formats are read), `cspace`
(the configuration space's metric and motions; numpy only), `shapes`, `offline`.
"""
