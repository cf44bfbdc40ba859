"""Mesh obstacles and mesh robots for Drake (stage (b) of a custom scene's route): format conversion (`reading`),
convex pieces (`pieces`, CoACD in `coacd_process`), the method (`decomposition`), validation (`validation`), hulls
split and merged to a bound (`merging`) and an on-disk cache (`cache`, whose `decompose` is the entry
point: one mesh file in, its pieces out). No Drake here: what a scene does with the pieces is
app.scene.prepare_meshes' and app.scene.emit's.

Drake reads .obj/.vtk/.gltf for collision (not .stl/.dae) and its proximity engine treats a mesh as its convex hull,
so a non-convex mesh must become a set of convex pieces. By default (method "auto") every mesh is bounded
(`decomposition._bounds`, `merging`): the hull of its faces, split in halves until every hull's surface lies within
a reach of the mesh or inside its parts, then merged pairwise, least added volume first, under the same rule. The
reach is MERGE_REACH (5 mm; the caller gives the link's scale) for a robot's link, merged towards MOST_LINK_PIECES,
and the mesh's tolerance for any other mesh (an obstacle, a mesh robot), merged as far as the rule allows. So the
pieces are never smaller than the mesh (each face lies in a hull), never collide falsely where the mesh has the reach
of clearance, and a CAD mesh of tens of thousands of triangles or a scene export of thousands of loose faces, open or
closed, becomes tens of hulls in seconds to a minute. Methods asked for by name (`--mesh-method`), per connected
part:

- "convex": each part's hull (merged by `hull_groups`), bounds exempt from the free-space test.
- "shell": closed parts only: pieces that reach into the part's own solid, where the robot cannot be anyway
  (`shell_pieces`). A patch of faces plus its corners moved inward by half the wall's thickness, as one convex
  hull, grows while it holds no other point of the surface deeper than SHELL_REACH * tolerance. Pieces that fail
  validation become face pieces (once).
- "coacd": CoACD approximate decomposition, pre-processing off (it thickens thin walls), in a child process with a
  time limit (it can crash or run for minutes).
- "faces": exact pieces. Adjacent faces are grown into one piece while they fit in a slab of width `tolerance / 2`
  along the seed face's normal and their projection onto that plane is nearly convex (all faces facing the same
  way; the 2-D hull's area exceeds the projected faces' by at most a rim of mean width slab/2 along its perimeter),
  so every point of the piece lies within about tolerance/2 (+ thickness/2) of the original surface. Each piece is
  that flat convex polygon extruded by `thickness` = tolerance/5 (a prism).

A robot link's pieces by a named method are then merged within MERGE_REACH. `volume_report` states what the pieces
add.

A named method's pieces are validated against the original surface (`validate`); pieces that hold free points are
refused (a UserError). The result, or the failure, is cached on disk (`cache_root()`), keyed by the mesh
file's content hash, the method request, the parameters, DECOMPOSER_VERSION and CoACD's version. An entry's manifest
holds a sha256 of every file, and the manifest itself is sealed with an HMAC-SHA256 under a per-user secret key kept
outside the cache (`key_path()`): checksums alone only catch accidents, since whoever writes a cache folder can write
matching checksums for pieces that do not contain the mesh (a false "free" for the planner). An entry whose seal is
missing or wrong is rebuilt, not trusted; so is a converted .obj (`converted_obj`), sealed the same way. Entries are
built in a staging folder and renamed into place, so concurrent runs see a whole entry or none.

Load cost: SceneGraph's registration cost grows quadratically with the number of geometries (docs/benchmarks-history.md,
"Mesh scenes"), so few pieces matter as much as tight ones.
(Check cost need not grow so: app.scene.emit anchors environment pieces to the world, see `env_urdf`.)

The tolerance is the caller's choice; `default_tolerance` (0.2 % of the mesh's size) knows nothing of the robot, so
app.scene.custom derives environment tolerances from the edge-check step instead.
"""
