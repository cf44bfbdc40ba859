"""The collision-checking stage: one shared checker per scene (`oracle`), the per-query context that counts and
bounds a query's checks (`context`, `budget`), the interface the later stages see (`protocol`), and the continuous
certificate that proves a motion free between checked points (`certify`, with numpy forward kinematics in
`kinematics`)."""
