"""Loading a bundle: the peak memory ``OnnxPipeline`` takes against the file's size.

A bundle is checked against its digest and loaded by onnxruntime (:class:`tactile_torch.robot.runtime.
OnnxPipeline`). For bundles of 50 and 200 MiB of weights (a linear classifier of the mean frame, numpy
encoded, sealed), each loaded in a fresh process: the peak resident memory the load adds over the
process's imports (``ru_maxrss``), as a multiple of the file's size; against, in the same run, what a
user would write: the file read whole, its digest checked, and onnxruntime given the bytes
(``InferenceSession(path.read_bytes())``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

TITLE = "Loading a bundle: peak memory against its size"

_LOAD = """
import os, sys
os.environ["TACTILE_TORCH_MAX_READ_MB"] = "100000"
import numpy, onnxruntime
from tactile_torch.robot import integrity, runtime
def peak():  # this process's high-water mark (ru_maxrss would carry the parent's over exec)
    line = next(l for l in open("/proc/self/status") if l.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024
base = peak()
if sys.argv[2] == "ours":
    runtime.OnnxPipeline(sys.argv[1])
else:
    data = open(sys.argv[1], "rb").read()
    integrity.check_digest(data, sys.argv[1])
    onnxruntime.InferenceSession(data, providers=["CPUExecutionProvider"])
print(peak() - base)
"""


def _peak_mib(path: str, how: str) -> float:
    out = subprocess.run([sys.executable, "-c", _LOAD, path, how], capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def run(quick: bool) -> dict:
    import numpy as np

    from tests.stream_helpers import frame_bundle

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mib in (50,) if quick else (50, 200):
            channels = mib * 2**20 // (4 * 512 * 512)
            path = os.path.join(tmp, f"b{mib}.onnx")
            frame_bundle(path, np.ones((512, 512, channels), np.float32), n_frames=2)
            size = os.path.getsize(path) / 2**20
            ours, whole = _peak_mib(path, "ours"), _peak_mib(path, "whole")
            rows.append(
                {
                    "bundle MiB": round(size, 1),
                    "OnnxPipeline peak MiB": round(ours),
                    "x file": round(ours / size, 2),
                    "read whole + check + load MiB": round(whole),
                    "x file (whole)": round(whole / size, 2),
                }
            )
    notes = [
        "Peak resident memory added by the load (the process's VmHWM after, minus after the imports), one fresh "
        "process per load; OnnxPipeline checks the digest in 1 MiB chunks and has onnxruntime load the same open "
        "file.",
        "Machine shared with other developers' jobs: memory is not affected by their load.",
    ]
    return {"rows": rows, "notes": notes}


if __name__ == "__main__":
    print(run(quick=True))
