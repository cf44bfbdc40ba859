"""Command modules, in the order `--help` lists them. Each has `register(subparsers)`.

Beside them: `common` (argument types, the JSON answer), `custom` (the --robot/--env flags) and the viewer flags
in `view`, shared by the commands that take them.
"""

from app.commands import bench, gui, plan, roadmap, run, sample, scenes, view

MODULES = [scenes, sample, plan, roadmap, run, view, gui, bench]
