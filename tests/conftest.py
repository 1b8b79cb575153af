import os

# Tests share the 2-core machine with each other: keep torch from spawning a thread per core per worker.
os.environ.setdefault("OMP_NUM_THREADS", "1")
