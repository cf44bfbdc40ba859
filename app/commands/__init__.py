"""Command modules, in the order `--help` lists them. Each has `register(subparsers)`."""
from app.commands import bench, scenes

MODULES = [scenes, bench]
