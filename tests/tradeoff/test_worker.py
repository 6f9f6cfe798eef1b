"""The trade-off's background export process ends with its parent, even in the middle of a job.

Issue 41: after ``tradeoff`` was killed (SIGKILL) its export worker lived on. The worker here runs a
30-second job for a parent that is then killed: it is gone within a couple of seconds.
"""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import time

PARENT = """
import subprocess, sys, time
worker = subprocess.Popen([sys.executable, "-m", "tactile_torch.tradeoff._worker"], stdin=subprocess.PIPE, text=True)
worker.stdin.write(sys.argv[1] + "\\n")
worker.stdin.flush()
print(worker.pid, flush=True)
time.sleep(60)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as stat:  # a zombie is gone, only not yet reaped
        return stat.read().split()[2] != "Z"


def test_the_export_worker_ends_when_its_parent_is_killed(tmp_path):
    job = tmp_path / "job.pkl"
    job.write_bytes(pickle.dumps((time.sleep, (30,))))  # a job as long as an export
    parent = subprocess.Popen([sys.executable, "-c", PARENT, str(job)], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(parent.stdout.readline())
        time.sleep(1.0)  # the worker has started the job (it imports nothing heavy)
        assert _alive(worker)
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 5
        while _alive(worker) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(worker)
    finally:
        parent.kill()
