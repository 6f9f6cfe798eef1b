"""Peak resident memory of an onnxruntime session running a bundle at batch 1, measured in a fresh process.

Definition (:func:`peak_memory_mib`): a child Python process imports numpy and onnxruntime, reads the
peak resident set size so far (``VmHWM`` of ``/proc/self/status``; ``resource.getrusage`` ``ru_maxrss``
where ``/proc`` is absent), then creates the session (one intra-op and one inter-op thread, as
:class:`~tactile_torch.robot.runtime.OnnxPipeline` does) and runs one sample ``repeat`` times. The result is the
increase of the peak: the memory the model costs on top of an interpreter that already has onnxruntime
loaded (weights, the session's arenas and the activations of one inference). It is a process-level
figure: allocator granularity makes differences below about 1 MiB noise. The raw sample travels in a
``.npy`` file read with ``allow_pickle=False``.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

_CHILD = r"""
import json, resource, sys
import numpy as np
import onnxruntime as ort

def peak_kib():
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss // 1024 if sys.platform == "darwin" else rss

model, sample, repeat = sys.argv[1], sys.argv[2], int(sys.argv[3])
raw = np.load(sample, allow_pickle=False)
before = peak_kib()
options = ort.SessionOptions()
options.intra_op_num_threads = 1
options.inter_op_num_threads = 1
session = ort.InferenceSession(model, options, providers=["CPUExecutionProvider"])
name = session.get_inputs()[0].name
for _ in range(repeat):
    session.run(None, {name: raw})
print(json.dumps({"before_kib": before, "after_kib": peak_kib()}))
"""


def peak_memory_mib(
    path: str | Path, sample: np.ndarray, *, repeat: int = 3, timeout_s: float = 120.0
) -> float:
    """Return the peak resident memory (MiB) a session of bundle ``path`` adds when running ``sample``.

    Parameters
    ----------
    path : path
        An ``.onnx`` file.
    sample : ndarray of shape (1, ...)
        One raw input in the graph's dtype.
    repeat : int
        Inferences run.
    timeout_s : float
        The child process is stopped after this long (``subprocess.TimeoutExpired``).

    Raises
    ------
    RuntimeError
        If the child process fails (its last line of stderr in the message).
    """
    sample = np.ascontiguousarray(sample)
    if sample.ndim < 1 or sample.shape[0] != 1:
        raise ValueError(f"sample must hold one raw input (batch 1), got shape {sample.shape}")
    with tempfile.TemporaryDirectory(prefix="tactile-torch-memory-") as tmp:
        npy = Path(tmp) / "sample.npy"
        np.save(npy, sample, allow_pickle=False)
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, str(path), str(npy), str(int(repeat))],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            check=False,
        )
    if done.returncode != 0:
        lines = [line for line in done.stderr.splitlines() if line.strip()]
        raise RuntimeError(f"memory measurement of {path} failed: {(lines or ['no output'])[-1]}")
    values = json.loads(done.stdout.strip().splitlines()[-1])
    return max(0.0, (values["after_kib"] - values["before_kib"]) / 1024.0)


__all__ = ["peak_memory_mib"]
