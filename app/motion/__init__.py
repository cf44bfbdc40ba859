"""The motion stage: paths (shortcuts, checks, `path`), their time parameterization (`timing`: Toppra per leg in
`leg_timing`, corners rounded and proved in `blends`, the samples a controller receives in `trajectory_samples`), the
trajectory that a robot executes and every command writes (`trajectory`), and ROS 2 bags of it (`rosbag`)."""
