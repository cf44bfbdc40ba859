"""Mesh obstacles and mesh robots for Drake (stage (b) of a custom scene's route): format conversion (`reading`),
convex pieces (`pieces`, CoACD in `coacd_process`), the method per part (`decomposition`), validation (`validation`),
robot links' pieces merged to a bound (`merging`) and an on-disk cache (`cache`, whose `decompose` is the entry
point: one mesh file in, its pieces out). No Drake here: what a scene does with the pieces is
app.scene.prepare_meshes' and app.scene.emit's.

Drake reads .obj/.vtk/.gltf for collision (not .stl/.dae) and its proximity engine treats a mesh as its convex hull,
so a non-convex mesh must become a set of convex pieces. The mesh is split into connected parts (faces sharing an
edge) and a method is chosen per part (`decomposition.choose_method`):

- "convex": the part is closed (watertight, consistently wound, positive volume) and equals its own hull: 1 piece.
- "shell": closed but not convex: pieces that reach into the part's own solid, where the robot cannot be anyway
  (`shell_pieces`). A patch of faces plus its corners moved inward by half the wall's thickness, as one convex
  hull, grows while it holds no other point of the surface deeper than SHELL_REACH * tolerance. A side that bulges
  outward (a sphere seen from outside, a thick wall's face) becomes a few large caps; a hollow side stays within
  reach of flat. Seconds on a few thousand triangles, with far fewer pieces than "faces" makes and where CoACD can
  fail validation (docs/benchmarks-history.md, "Mesh scenes"). Pieces that fail validation become face pieces (once); if
  the part still fails, it moves on to "coacd".
- "coacd": CoACD approximate decomposition, pre-processing off (it thickens thin walls), in a child process with a
  time limit (it can crash or run for minutes). Falls back to "faces" when it fails or its pieces fail validation.
- "faces": open or thin parts (typical COLLADA scene exports): exact pieces. Adjacent faces are grown into one
  piece while they fit in a slab of width `tolerance / 2` along the seed face's normal and their projection onto
  that plane is nearly convex (all faces facing the same way; the 2-D hull's area exceeds the projected faces' by at
  most a rim of mean width slab/2 along its perimeter: a curved surface projects to a slightly non-convex outline,
  and an exact test stopped most patches at two triangles), so every point of the piece lies within about
  tolerance/2 (+ thickness/2) of the original surface. Coplanar adjacent triangles are the exact special case.
  Each piece is that flat convex polygon extruded by `thickness` = tolerance/5 (a prism).

Robot links (`conservative`, method "auto") are bounded, not decomposed (`merging`, by
`decomposition._link_bounds`): the hull of the link's faces, split in halves until every hull's surface lies within
MERGE_REACH (5 mm; the caller gives the link's scale) of the mesh or inside its parts, then merged pairwise, least
added volume first, towards MOST_LINK_PIECES under the same rule. So a link is never smaller than its mesh (each face
lies in a hull), never collides falsely where its mesh has 5 mm of clearance, and a CAD mesh of tens of thousands of
triangles, open or closed, takes seconds. A method asked for by name is used as for any mesh, its pieces then merged
within MERGE_REACH; `--mesh-method convex` takes every part's hull (merged by `hull_groups`), bounds exempt from the
free-space test. `volume_report` states what the pieces add. Environment meshes are not merged.

Every decomposition is validated against the original surface (`validate`); parts whose pieces hold free points
move on to their next method. The result, or the failure, is cached on disk (`cache_root()`), keyed by the mesh
file's content hash, the method request, the parameters, DECOMPOSER_VERSION and CoACD's version. An entry's manifest
holds a sha256 of every file, and the manifest itself is sealed with an HMAC-SHA256 under a per-user secret key kept
outside the cache (`key_path()`): checksums alone only catch accidents, since whoever writes a cache folder can write
matching checksums for pieces that do not contain the mesh (a false "free" for the planner). An entry whose seal is
missing or wrong is rebuilt, not trusted; so is a converted .obj (`converted_obj`), sealed the same way. Entries are
built in a staging folder and renamed into place, so concurrent runs see a whole entry or none.

Load cost: SceneGraph's registration cost grows quadratically with the number of geometries (docs/benchmarks-history.md,
"Mesh scenes"), so merging faces into few pieces matters as much as the decomposition.
(Check cost need not grow so: app.scene.emit anchors environment pieces to the world, see `env_urdf`.)

The tolerance is the caller's choice; `default_tolerance` (0.2 % of the mesh's size) knows nothing of the robot, so
app.scene.custom derives environment tolerances from the edge-check step instead.
"""
