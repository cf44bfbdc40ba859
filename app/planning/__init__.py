"""The planning stage: the roadmap graph (`roadmap`), the single query (`planner`), and inverse kinematics for pose
goals (`ik`)."""
