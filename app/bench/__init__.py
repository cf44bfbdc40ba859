"""Experiments and benchmarks: each module measures one thing side by side with its peer."""
