"""The host's job lock: a job that finds another run holding it says so before it waits."""
import fcntl
import threading
import time

from matrix.hostlock import host_slot, lock_path


def test_a_job_waiting_for_another_run_s_timing_job_says_so_then_runs(tmp_path, monkeypatch):
    """Outside test: a job blocked on another run's timing job showed as running, "about 0:00:00 left",
    for as long as that job took, with no word of why."""
    monkeypatch.setenv("MATRIX_HOST_LOCK", str(tmp_path / "host.lock"))
    told, ran = [], threading.Event()
    with open(lock_path(), "a") as other:              # another run's timing job, alone on the host
        fcntl.flock(other, fcntl.LOCK_EX)

        def job():
            with host_slot(exclusive=False, waiting=lambda: told.append(time.monotonic())):
                ran.set()
        thread = threading.Thread(target=job)
        thread.start()
        time.sleep(0.3)
        assert told and not ran.is_set()
        fcntl.flock(other, fcntl.LOCK_UN)
    thread.join(timeout=10)
    assert ran.is_set() and len(told) == 1
    with host_slot(exclusive=True, waiting=lambda: told.append(0.0)):   # nothing holds it: no word
        pass
    assert len(told) == 1


def test_a_job_meeting_another_at_the_turnstile_for_a_moment_says_nothing(tmp_path, monkeypatch):
    """CI: two jobs starting at one instant met at the turnstile (every holder passes it), and one said
    it waited for the host, a word that stayed on its progress line while it ran."""
    monkeypatch.setenv("MATRIX_HOST_LOCK", str(tmp_path / "host.lock"))
    told = []
    with open(lock_path().with_suffix(".turnstile"), "a") as other:    # another job passing it now
        fcntl.flock(other, fcntl.LOCK_EX)
        threading.Timer(0.05, fcntl.flock, (other, fcntl.LOCK_UN)).start()
        with host_slot(exclusive=False, waiting=lambda: told.append("waiting"),
                       resumed=lambda: told.append("resumed")):
            pass
    assert told == []


def test_a_job_that_waited_for_the_host_says_when_it_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("MATRIX_HOST_LOCK", str(tmp_path / "host.lock"))
    told = []
    with open(lock_path(), "a") as other:              # another run's timing job, alone on the host
        fcntl.flock(other, fcntl.LOCK_EX)
        threading.Timer(0.6, fcntl.flock, (other, fcntl.LOCK_UN)).start()
        with host_slot(exclusive=False, waiting=lambda: told.append("waiting"),
                       resumed=lambda: told.append("resumed")):
            told.append("ran")
    assert told == ["waiting", "resumed", "ran"]
