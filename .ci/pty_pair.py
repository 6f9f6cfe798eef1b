"""A null-modem cable made of two pseudo-terminals (what ``socat pty pty`` does), for the robot CI job.

Prints the two terminal names on one line (``A B``), then copies every byte written to ``A`` to the
reader of ``B`` (and back) until it is terminated. A sensor simulator writes to ``A``; a serial
reader opens ``B`` as it would a USB serial port. Standard library only (runs in the runtime venv).
"""

from __future__ import annotations

import os
import select
import signal
import sys
import tty


def main() -> int:
    ends = [os.openpty() for _ in range(2)]  # (master, slave) twice; the slaves stay open here
    for _, slave in ends:
        tty.setraw(slave)  # no echo, no line editing: bytes pass unchanged (and never bounce back)
    print(" ".join(os.ttyname(slave) for _, slave in ends), flush=True)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    (a, _), (b, _) = ends
    peer = {a: b, b: a}
    while True:
        ready, _, _ = select.select([a, b], [], [])
        for fd in ready:
            try:
                data = os.read(fd, 65536)
            except OSError:  # EIO: nobody holds that terminal open right now
                continue
            os.write(peer[fd], data)  # blocks while the reader is slower: nothing is dropped


if __name__ == "__main__":
    raise SystemExit(main())
