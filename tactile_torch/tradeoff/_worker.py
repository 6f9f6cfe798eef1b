"""The background export process of :class:`tactile_torch.export.parts.ExportPool`.

Started as ``python -m tactile_torch.tradeoff._worker`` (a plain subprocess, so that the caller's
``__main__`` is never re-imported, unlike ``multiprocessing``'s spawn). Reads one line per job from
stdin: the path of a pickled ``(function, args)`` that its parent wrote moments before to a private
temporary directory; runs it and answers one line on its stdout: ``ok <result>`` or ``error <message>``.
Anything the exporter prints goes to stderr.
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path


def main() -> int:
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
