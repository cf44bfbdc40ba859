"""The motion stage: paths (shortcuts, checks, `path`), their time parameterization (`timing`, Toppra) and the
trajectory that a robot executes and every command writes (`trajectory`)."""
