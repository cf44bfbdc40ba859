"""Narrow-passage PRM planning on Drake."""
import os

# Drake's parallel collision batches use OpenMP. By default its idle threads spin for a while after each batch,
# holding the second core while the Python loop that follows wants it: with many small batches (walkers, edge
# rounds) that made 2 threads slower than 1. Passive waiting gives the core back. Must be set before libgomp loads.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
