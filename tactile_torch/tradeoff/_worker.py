"""The background export process of :class:`tactile_torch.export.parts.ExportPool`.

Started as ``python -m tactile_torch.tradeoff._worker`` (a plain subprocess, so that the caller's
``__main__`` is never re-imported, unlike ``multiprocessing``'s spawn). Reads one line per job from
stdin: the path of a pickled ``(function, args)`` that its parent wrote moments before to a private
temporary directory; runs it and answers one line on its stdout: ``ok <result>`` or ``error <message>``.
Anything the exporter prints goes to stderr. It ends with its parent, even in the middle of a job: a
study killed with SIGKILL leaves no export running on (:func:`end_with_parent`).
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path


def end_with_parent(poll_s: float = 0.2) -> None:
    """End this process when its parent ends, however it ends (SIGKILL included).

    On Linux the kernel sends SIGKILL at once (``PR_SET_PDEATHSIG``); everywhere a daemon thread also
    watches the parent's process id (a child whose parent died is adopted by another) every ``poll_s``.
    """
    import sys
    import threading
    import time

    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass  # the thread below still watches

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def main() -> int:
    end_with_parent()
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # the exporter's own output must not mix with the answers
    for line in sys.stdin:
        job = Path(line.strip())
        try:
            fn, args = pickle.loads(job.read_bytes())
            answer = f"ok {fn(*args)}"
        except Exception as err:
            lines = [text for text in str(err).splitlines() if text.strip()]
            answer = f"error {type(err).__name__}: {(lines or [''])[-1][:300]}"
        finally:
            job.unlink(missing_ok=True)
        answers.write(answer.replace("\n", " ") + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
