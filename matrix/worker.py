"""Running one job, wherever it runs (a local worker process or a Dask worker).

`execute_job` takes the job's spec as plain data, reads its dependencies' results from the store,
runs the registered handler in a private folder and commits the result atomically, all under the
job's lock, so two runs sharing a store never run the same job at once.
"""
from __future__ import annotations

import atexit
import contextlib
import ctypes
import importlib
import logging
import math
import os
import signal
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from matrix.errors import MatrixError, exit_message, full_traceback
from matrix.hostlock import host_slot
from matrix.jobs import spec_dep_keys
from matrix.kinds import KINDS, DepResult, JobContext, NotApplicable
from matrix.runs import BUSY, DONE_ELSEWHERE, FAILED, KEPT, NOT_APPLICABLE, OK
from matrix.stale import CONDITIONAL
from matrix.store import INTACT, LOG, Store, outputs_token, result_token

_progress_sink: Callable[[str, dict], None] | None = None
PR_SET_PDEATHSIG = 1  # linux/prctl.h
_capture_fds = False  # our own pool workers run one job at a time, so they may take over fds 1 and 2


THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def init_worker(kind_modules: Iterable[str], progress_queue: Any = None, threads: int | None = None) -> None:
    """Process-pool initializer: register the domain's job kinds; send progress to the driver.

    `threads`: the worker's share of the cores, for OpenMP/BLAS libraries (read when they load, so set
    before the kinds' modules import them). Two workers each running torch on both of 2 cores spin
    against each other (a 2-epoch fine-tune took minutes instead of seconds); a job that needs a set
    thread count (a timing job) sets it itself. A variable the user set is kept."""
    global _progress_sink, _capture_fds
    _capture_fds = True
    _die_with_parent()
    # Idle, a worker ignores Ctrl-C and a SIGTERM sent to the run's process group (`timeout`, a batch system):
    # the driver stops the pool (an idle worker printed a traceback from its queue wait; killed by SIGTERM,
    # it was reported as crashed, its job as failed); a job it runs is interrupted (execute_job)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _sigterm_when_idle)
    for variable in THREAD_VARIABLES if threads else ():
        os.environ.setdefault(variable, str(threads))
    for module in kind_modules:
        importlib.import_module(module)
    if progress_queue is not None:
        _progress_sink = lambda key, update: progress_queue.put((key, update))
    atexit.register(_exit_now)


def _exit_now() -> None:
    """Registered as the worker starts, this atexit handler runs after those of the modules its jobs
    imported later (atexit runs the last registered first), then ends the process without the
    interpreter's teardown (each loaded module's, torch's and TensorFlow's: 0.7-1.9 s that the run waited
    for at its end, with nothing left to do). Everything a job wrote is on disk when its result returns,
    and multiprocessing has flushed its queues before the interpreter exits."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _sigterm_when_idle(signum, frame) -> None:
    if os.getppid() != _parent[0]:    # the run died (PR_SET_PDEATHSIG): go with it
        os._exit(1)


def _sigterm_in_a_job(signum, frame) -> None:
    _sigterm_when_idle(signum, frame)
    raise KeyboardInterrupt           # the run stops: the job is interrupted as at Ctrl-C


_parent = [0]


def _die_with_parent() -> None:
    """On Linux, the worker gets SIGTERM when the run that started it dies (killed by a job manager, a
    timeout or `kill`), instead of running its job on as an orphan holding a core. (Ctrl-C reaches
    the workers anyway: they are in the run's process group.)"""
    _parent[0] = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):   # not Linux
        return
    if os.getppid() == 1:               # the run died before prctl took effect
        os._exit(1)


def execute_job(store_root: str, spec: dict, kind_modules: Iterable[str] = (), replaces: str | None = None,
                run: str | None = None) -> dict:
    """Run the job described by `spec` (see Job.spec) unless it is done or running elsewhere.
    `replaces` (a forced rerun) names the stored result to run again: that one does not count as done.
    `run` names the run it belongs to: its dependencies' files are hashed in full once per run (matrix.store).

    Returns {"status": ok | not_applicable | failed | busy | done_elsewhere | kept, "reason", "duration_s"}."""
    with _interruptible():
        return _execute(store_root, spec, kind_modules, replaces, run)


@contextlib.contextmanager
def _interruptible():
    """In a pool worker (which ignores Ctrl-C and SIGTERM while idle), either interrupts the job it runs."""
    if not _capture_fds:   # not our pool's worker (the driver, a Dask worker's thread): as it is
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _sigterm_in_a_job)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _sigterm_when_idle)


def _execute(store_root: str, spec: dict, kind_modules: Iterable[str], replaces: str | None, run: str | None) -> dict:
    for module in kind_modules:
        importlib.import_module(module)
    store, key = Store(store_root), spec["key"]
    with store.lock(key) as held:
        if not held:
            return {"status": BUSY, "reason": "running in another process"}
        done = store.result(key)
        kept = done is not None and store.outputs_intact(key, done) and _still_stands(store, spec, done, replaces)
        if kept:
            store.forget_failure(key)   # `status` counted it as failed after a run had kept its result
            return {"status": KEPT, "reason": kept, "duration_s": 0.0} if isinstance(kept, str) else \
                {"status": DONE_ELSEWHERE, "reason": done.get("reason", ""), "duration_s": 0.0}
        with host_slot(exclusive=KINDS.get(spec["kind"]).runs_alone(spec["params"]),   # timings: alone
                       waiting=lambda: _progress_for(key)(completed=0, total=None, description=HOST_BUSY),
                       resumed=lambda: _progress_for(key)(completed=0, total=None, description=RUNNING)):
            return _run_locked(store, spec, run)


def _still_stands(store: Store, spec: dict, done: dict, replaces: str | None) -> bool | str:
    """Whether the stored result `done` is kept: it is not the one to replace (another run replaced it
    already), or it was to be replaced only if its dependencies' outputs changed and they did not (then
    the reason, in words)."""
    conditional = replaces is not None and replaces.startswith(CONDITIONAL)
    if result_token(done) != (replaces.removeprefix(CONDITIONAL) if conditional else replaces):
        return True
    if conditional and done.get("deps_used") == _dependency_outputs(store, spec):
        return "kept: its dependencies ran again with the outputs it was made from"
    return False


def _dependency_outputs(store: Store, spec: dict) -> dict[str, str | None]:
    return {key: None if (result := store.result(key)) is None else outputs_token(result)
            for key in spec_dep_keys(spec["deps"])}


def _run_locked(store: Store, spec: dict, run: str | None) -> dict:
    key, started = spec["key"], time.time()
    workdir = store.new_workdir(key)
    try:
        used: dict[str, str] = {}
        deps = _dep_results(store, spec, used, run)
        blocker = _not_applicable_dep(deps)
        if blocker:
            status, reason, value = NOT_APPLICABLE, blocker.reason, {}
        else:
            status, reason, value = _call_handler(store, spec, deps, workdir)
    except Exception as error:  # a failing handler is reported, never crashes the run
        return _fail(store, spec, workdir, error, started)
    result = {"status": status, "reason": reason, "value": value, "duration_s": time.time() - started,
              "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "deps_used": used}
    if blocker:   # the reason stays the dependency's own, so cells blocked for one cause group together
        result["blocked_by"] = blocker.name
    store.commit(key, workdir, spec, result, measured=KINDS.get(spec["kind"]).measured, run=run)
    shown = f"{reason} ({blocker.name})" if blocker else reason
    return {"status": status, "reason": shown, "duration_s": result["duration_s"]}


def _call_handler(store: Store, spec: dict, deps: dict, workdir: Path) -> tuple[str, str, dict]:
    kind = KINDS.get(spec["kind"])
    with _job_log(workdir / LOG, spec) as log:
        ctx = JobContext(key=spec["key"], kind=spec["kind"], name=spec["name"], params=spec["params"],
                         deps=deps, inputs={r: Path(f["path"]) for r, f in spec["inputs"].items()},
                         out=workdir / "artifacts", cache=store.cache, log=log,
                         _progress=_progress_for(spec["key"]))
        try:
            value = kind.handler(ctx)
        except NotApplicable as na:
            log.info("not applicable: %s", na)
            return NOT_APPLICABLE, str(na), {}
        except SystemExit as exit_:   # else it would pass the pool and end the whole run with its code
            raise MatrixError(exit_message(exit_)) from exit_
    value = dict(value or {})
    where = non_finite(value)
    if where:
        raise MatrixError(f"the job's result holds a number that is not finite ({where}): "
                          "a NaN or infinite result is never reported as ok; see its log")
    return OK, "", value


def non_finite(value: Any, path: str = "") -> str | None:
    """'key.path = nan' of the first NaN or infinite float in a result, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return f"{path or 'value'} = {value}"
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, (list, tuple)) else ()
    for key, item in items:
        found = non_finite(item, f"{path}.{key}" if path else str(key))
        if found:
            return found
    return None


def _dep_results(store: Store, spec: dict, used: dict[str, str],
                 run: str | None = None) -> dict[str, DepResult | tuple[DepResult, ...]]:
    """The dependencies' results as the handler sees them; `used` gets the outputs token of each (the
    job's result records them: a dependency that runs again later with other outputs makes it stale).
    Their files are hashed in full first, but for what `run` made or hashed in full already."""
    def one(key: str) -> DepResult:
        result, dep_spec = store.result(key), store.spec(key) or {}
        if result is None:
            raise RuntimeError(f"dependency {key[:12]} has no result in {store.root}")
        used[key] = outputs_token(result)
        outputs = store.outputs_state(key, result, full=True, run=run)   # hashed before the handler reads them
        if outputs != INTACT:
            raise RuntimeError(f"dependency {dep_spec.get('name', key[:12])}: output {outputs} since its job "
                               "wrote it (a file in its artifacts is not the one recorded); the next run "
                               "rebuilds it")
        return DepResult(key, dep_spec.get("kind", ""), dep_spec.get("params", {}),
                         result.get("value", {}), store.artifacts(key), dep_spec.get("name", key[:12]),
                         result["status"], result.get("reason", ""))
    return {role: tuple(one(k) for k in keys) if isinstance(keys, list) else one(keys)
            for role, keys in spec["deps"].items()}


def _not_applicable_dep(deps: dict) -> DepResult | None:
    """The first dependency that was not applicable: this job is not applicable for the same reason."""
    for dep in (d for value in deps.values() for d in (value if isinstance(value, tuple) else (value,))):
        if dep.status == NOT_APPLICABLE:
            return dep
    return None


RUNNING = "running"   # what a job's line says once the host it waited for is free, until the job says more
# short enough for the progress line's 30 characters (an outside test read "waiting for this host: anothe…"):
# another job has the host to itself (a timing, of this run or another), or this one must and others run
HOST_BUSY = "waiting for this host's lock"
MESSAGE_LIMIT, BUG_LIMIT = 2000, 300   # characters of a failure's line: the domain's own message, anything else


def failure_message(error: Exception) -> str:
    """One line a user can act on: an error the domain raised on purpose (MatrixError) is its own
    message, whole (its fix often comes last, after a listing: cut at 300 characters, the advice was
    lost); anything else is a bug, shown with its type (the traceback is in the failure record)."""
    text = str(error).strip()
    limit = MESSAGE_LIMIT if isinstance(error, MatrixError) and text else BUG_LIMIT
    if not isinstance(error, MatrixError) or not text:
        text = f"{type(error).__name__}: {text}" if text else type(error).__name__
    line = text.splitlines()[0]
    return line if len(line) <= limit else line[:limit - 1].rstrip() + "…"


def _fail(store: Store, spec: dict, workdir: Path, error: Exception, started: float) -> dict:
    message = failure_message(error)
    log_tail = _tail(workdir / LOG)
    store.record_failure(spec["key"], {"error": message, "expected": isinstance(error, MatrixError),
                                       "traceback": full_traceback(error),
                                       "log_tail": log_tail, "spec": spec, "workdir": str(workdir)})
    return {"status": FAILED, "reason": message, "duration_s": time.time() - started}


def _tail(path: Path, lines: int = 30) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


@contextlib.contextmanager
def _job_log(path: Path, spec: dict):
    """A logger writing to the job's log.txt; the handler's prints go there too."""
    logger = logging.getLogger(f"matrix.job.{spec['key'][:12]}")
    logger.setLevel(logging.INFO)
    logger.propagate = False
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    logger.addHandler(handler)
    try:
        with _job_output(handler.stream):
            logger.info("%s %s (%s)", spec["kind"], spec["name"], spec["key"])
            yield logger
    finally:
        logger.removeHandler(handler)
        handler.close()
        _cap_log(path)


MAX_LOG_BYTES = 2_000_000   # a job's log.txt keeps its first and last million bytes


def _cap_log(path: Path, limit: int = MAX_LOG_BYTES) -> None:
    """A job that printed megabytes (a network printing on every call) keeps the start and the end
    of its log, with a line saying how much was cut: the store does not grow with its chatter."""
    try:
        size = path.stat().st_size
        if size <= limit:
            return
        with open(path, "r+b") as log:
            head = log.read(limit // 2)
            log.seek(size - limit // 2)
            tail = log.read()
            note = f"\n[... {size - len(head) - len(tail):,} bytes of output cut: the log keeps its first and last " \
                   f"{limit // 2:,} bytes ...]\n".encode()
            log.seek(0)
            log.write(head + note + tail)
            log.truncate()
    except OSError:   # a log that cannot be cut is left whole
        pass


@contextlib.contextmanager
def _job_output(stream):
    """Prints of the job into its log. Our own workers move file descriptors 1 and 2 and keep
    sys.stdout/sys.stderr: a library that binds sys.stderr during one job (torch's logging does on
    import) must not hold that job's log file, closed when the next job logs through it. Dask workers
    run jobs in threads: there sys.stdout/sys.stderr are swapped instead."""
    if _capture_fds:
        with _captured_fds(stream):
            yield
    else:
        with contextlib.redirect_stdout(stream), contextlib.redirect_stderr(stream):
            yield


@contextlib.contextmanager
def _captured_fds(stream):
    """In our own worker processes, send file descriptors 1 and 2 to the job's log too, so what
    C libraries and other loggers print (warnings of torch, ONNX Runtime, pybullet) lands there
    instead of on the run's display. (Dask workers may run several jobs in threads: not there.)"""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    try:
        os.dup2(stream.fileno(), 1)
        os.dup2(stream.fileno(), 2)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        stream.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])


def _progress_for(key: str) -> Callable[..., None]:
    last = [0.0]

    def report(**update: Any) -> None:
        now = time.monotonic()
        done = update.get("total") is not None and update.get("completed") == update.get("total")
        if _progress_sink is not None and (done or now - last[0] > 0.2):
            last[0] = now
            _progress_sink(key, update)
    return report
