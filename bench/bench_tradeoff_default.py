"""The default trade-off study as the data grow: its time, what stopped early, and the deployed file's cost.

Two data sets shaped like users' own (``bench/tradeoff_sets.py``: a lab's 35 stylus logs of 30 s at
1 kHz in day folders, sessions that shift; a 4 x 4 fingertip's 186 explorations of 200 frames over 7
fabrics), each at its size and at 4x the data (4x the days, 4x the sessions), through the default
``tactile-torch tradeoff`` (no ``--quick``: every candidate, networks included, breaking points),
in one run, and once with ``--exhaustive`` at the issue's size for comparison:

- ``wall s`` and ``CPU s`` of the whole study (this process and its children), the machine's load
  (1-minute average) before and after: the machine is shared, compare within one run;
- the candidates, how many stopped early and after how many folds, and whether the recommendation is
  the exhaustive study's;
- the recommended file's latency as reported (measured on ``recommended.onnx``) against a second
  measurement of the same file here (same harness), and the temporal CNN's deployed bundle ("unknown"
  rule and all) against its bare network (the goal: within 2x);
- the estimates of the time left that the study printed, against the time it really had left (the
  largest factor between the two after the first tenth).
"""

from __future__ import annotations

import os
import re
import resource
import tempfile
import time
from pathlib import Path

TITLE = "Default trade-off study as the data grow: time, early stops, deployed cost (lab logs, 4x4 fingertip)"

CNN = "temporal CNN | raw maps"
SCALES_ENV = "TACTILE_TORCH_BENCH_SCALES"
KEEP_ENV = "TACTILE_TORCH_BENCH_KEEP"
"""A directory to keep the studies' outputs in (default: a temporary one, removed)."""


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _estimates(lines: list[tuple[float, str]], total: float) -> float | None:
    """The largest factor between an estimated total (elapsed + 'about X left') and the real one, after the
    first tenth of the study."""
    worst = None
    for at, line in lines:
        found = re.search(r"about (\d+) (s|min) left", line)
        if not found or at < total / 10:
            continue
        left = float(found.group(1)) * (60 if found.group(2) == "min" else 1)
        ratio = (at + left) / total
        factor = max(ratio, 1 / ratio) if ratio > 0 else float("inf")
        worst = factor if worst is None else max(worst, factor)
    return worst


def _study(data, options, out: Path) -> tuple[object, dict]:
    from tactile_torch.tradeoff.job import run_tradeoff_job

    lines: list[tuple[float, str]] = []
    load = os.getloadavg()[0]
    start, cpu = time.perf_counter(), _cpu()
    result, _ = run_tradeoff_job(
        data, options, out, progress=False, log=lambda text: lines.append((time.perf_counter() - start, text))
    )
    wall = time.perf_counter() - start
    stopped = [r for r in result.rows if r.get("stopped")]
    return result, {
        "wall s": round(wall, 1),
        "CPU s": round(_cpu() - cpu, 1),
        "load before/after": f"{load:.1f} / {os.getloadavg()[0]:.1f}",
        "candidates": len(result.rows),
        "stopped early (after folds)": f"{len(stopped)} ({', '.join(str(r['folds']) for r in stopped) or '-'})",
        "recommended": result.recommended or "-",
        "estimate off by at most": _estimates(lines, wall),
    }


def _recommended_latency(result, out: Path) -> tuple[float | None, float | None]:
    from tactile_torch.tradeoff.bundle import measure_file

    if result.recommended is None:
        return None, None
    row = result.row(result.recommended)
    s = result.inputs[result.result(result.recommended).candidate.input]
    again = measure_file(out / "recommended.onnx", s.X[:1], s.acquisition_s)["latency_ms"]
    return row["latency_ms"], again


def _cnn_ratio(result, out: Path) -> tuple[float, float] | None:
    """The temporal CNN's deployed bundle against its bare network (export_classifier of the same fold model)."""
    from tactile_torch.export import export_classifier
    from tactile_torch.tradeoff.bundle import measure_file

    deployed = next((d for d in result.deployed if d["name"] == CNN), None)
    if deployed is None:
        return None
    res = result.result(CNN)
    s = result.inputs[res.candidate.input]
    clf = res.model.steps[-1][1]
    bare = export_classifier(clf, out / "bare-cnn.onnx", s.X[:2])
    # the study wrote its files in a staging folder renamed to ``out`` at its end: the file by its name
    with_rule = measure_file(out / Path(deployed["onnx"]).name, s.X[:1], s.acquisition_s)["latency_ms"]
    alone = measure_file(bare, s.X[:1], s.acquisition_s)["latency_ms"]
    return with_rule, alone


def run(quick: bool) -> dict:
    from bench.tradeoff_sets import FINGERTIP_RATE_HZ, lab_logs, write_fingertip
    from tactile_torch.tradeoff.job import TradeoffOptions

    rows, notes = [], []
    # TACTILE_TORCH_BENCH_SCALES="1": the two sets at their size only (the 4x studies take the longest)
    scales = (1,) if quick else tuple(int(v) for v in os.environ.get(SCALES_ENV, "1,4").split(","))
    keep = os.environ.get(KEEP_ENV)  # the studies' outputs (charts, tradeoff.md) kept to be looked at
    with tempfile.TemporaryDirectory(prefix="bench-tradeoff-") as scratch:
        tmp = Path(keep) if keep else Path(scratch)
        datasets = []
        for scale in scales:
            datasets.append(("lab logs", scale, lab_logs(tmp / f"lab-{scale}", scale=scale), {}))
            tip = write_fingertip(tmp / f"fingertip-{scale}.npz", scale=scale)
            extra = {"frame_rate_hz": FINGERTIP_RATE_HZ}
            if not quick:  # a quick study has no networks (unless named): no CNN to deploy
                extra["deploy"] = CNN
            datasets.append(("fingertip", scale, tip, extra))
        exhaustive_choice = {}
        for name, scale, data, extra in datasets:
            for exhaustive in (False, True) if scale == 1 and not quick else (False,):
                options = TradeoffOptions(exhaustive=exhaustive, quick=quick, **extra)
                out = tmp / f"out-{name.replace(' ', '-')}-{scale}-{int(exhaustive)}"
                result, row = _study(data, options, out)
                reported, again = _recommended_latency(result, out)
                ratio = _cnn_ratio(result, out)
                if exhaustive:
                    exhaustive_choice[name] = result.recommended
                rows.append(
                    {
                        "data": f"{name}, {scale}x" + (" (--exhaustive)" if exhaustive else ""),
                        "samples": sum(len(s.y) for s in result.inputs.values()),
                        **row,
                        "recommended latency ms: reported / again": "-"
                        if reported is None
                        else f"{reported:.3g} / {again:.3g}",
                        "CNN deployed / bare ms": "-"
                        if ratio is None
                        else f"{ratio[0]:.3g} / {ratio[1]:.3g}",
                    }
                )
        for row in rows:
            name = row["data"].split(",")[0]
            if "exhaustive" not in row["data"] and row["data"].endswith("1x") and name in exhaustive_choice:
                row["same as --exhaustive"] = (
                    "yes" if row["recommended"] == (exhaustive_choice[name] or "-") else "no"
                )
    notes.append(
        "lab logs: 7 surfaces x 5 days (1x) or 20 days (4x), 30 s at 1 kHz each, CSV in day folders; fingertip: 7 "
        "fabrics, 186 (1x) or 744 (4x) explorations of 200 frames of 4 x 4 taxels at 100 Hz, 6 or 24 sessions"
    )
    notes.append(
        "the study caps the samples per class (300 by default): 4x the lab's logs adds windows beyond the cap "
        "(read, cut and deployed on, not cross-validated), 4x the fingertip's sessions adds explorations below it"
    )
    return {"rows": rows, "notes": notes}
