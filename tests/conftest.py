import os

# Tests share the 2-core machine with each other: keep torch from spawning a thread per core per worker.
os.environ.setdefault("OMP_NUM_THREADS", "1")

# Input-file hashes are remembered across processes (matrix.hashcache.HashCache): keep the tests'
# out of the user's cache folder.
os.environ.setdefault("MATRIX_HASH_CACHE", os.path.join(__import__("tempfile").gettempdir(),
                                                        "pilotlab-tests-file-hashes.sqlite"))

# Jobs hold a host-wide lock (matrix.hostlock); give this test session its own, so the tests of other
# checkouts running on the same machine do not wait for ours (and ours see only each other).
if "MATRIX_HOST_LOCK" not in os.environ:
    import tempfile
    os.environ["MATRIX_HOST_LOCK"] = os.path.join(tempfile.mkdtemp(prefix="matrix-tests-"), "host.lock")
