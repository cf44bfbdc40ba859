"""Command modules, in the order `--help` lists them. Each has `register(subparsers)`."""
from app.commands import bench, scenes, view

MODULES = [scenes, view, bench]
