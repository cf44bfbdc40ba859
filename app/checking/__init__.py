"""The collision-checking stage: one shared checker per scene (`oracle`, its batch paths, helper processes,
workspace queries and diagnostics in `batch_paths`, `helpers`, `workspace`, `diagnostics`), the per-query context
that counts and bounds a query's checks (`context`, `budget`), the interface the later stages see (`protocol`), and
the certificate that proves a motion free between checked points (`certify`, built on `motion_bound`,
`shape_gaps` and `end_distances`, with forward kinematics for many configurations in `kinematics`; the inner loops
of these compiled in `kernels`)."""
