"""Command modules, in the order `--help` lists them. Each has `register(subparsers)`."""
from app.commands import bench, plan, run, sample, scenes, view

MODULES = [scenes, sample, plan, run, view, bench]
