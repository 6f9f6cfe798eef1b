"""Coverage of the trade-off's accuracy interval on held-out sessions (issue 19, point 3).

For each generated data set (none is the bundled generator's default: other surfaces of the table,
other seeds, noise, session spread, class counts; one written as CSV logs ``<surface>_<session>.csv``
with two alike surfaces and a +-15 % gain per session), every session in turn is held out:
``tradeoff --quick`` runs on the other sessions, and the deployed ``recommended.onnx`` classifies the
held-out session. A case is *covered* when that accuracy lies inside the recommended candidate's
stated interval (a 95 % prediction interval for a new session; with fewer than 5 training sessions
the range over them, reported separately since it is not an interval).

    PYTHONPATH=. python train/interval_coverage.py --out runs/coverage     # writes coverage.json, prints a table
    PYTHONPATH=. python train/interval_coverage.py --classifiers LDA,NCM,kNN --windows 800   # fewer exports

Sessions are the unit (``session`` = the session number, shared by every surface's recording of that
session), so each held-out case is what a deployment meets: a new session of every surface.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _recordings(name: str, seed: int):
    from tactile_torch.data.stylus import SURFACES, make_vibration_recordings

    by_name = {s.name: s for s in SURFACES}
    if name == "8 surfaces x 6 sessions (table 13-20), seed 5, session jitter 0.08":
        rec = make_vibration_recordings(
            surfaces=SURFACES[12:20], n_sessions=6, duration_s=24, session_jitter=0.08, random_state=seed
        )
    elif name == "5 surfaces x 7 sessions (table 21-25), seed 9, noise 3 LSB, jitter 0.12":
        rec = make_vibration_recordings(
            surfaces=SURFACES[20:25],
            n_sessions=7,
            duration_s=24,
            noise_lsb=3,
            session_jitter=0.12,
            random_state=seed,
        )
    elif name.startswith("CSV 4 surfaces"):
        n_sessions = 6 if "x 6" in name else 4
        chosen = [by_name[n] for n in ("glass", "aluminium", "steel", "cork")]  # steel is alike aluminium
        rec = make_vibration_recordings(
            surfaces=chosen, n_sessions=n_sessions, duration_s=24, random_state=seed
        )
        gains = np.random.default_rng(seed + 1000).uniform(0.85, 1.15, n_sessions)  # +-15 % per session
        session = np.array([int(s.rsplit("/", 1)[1]) for s in rec.session])
        rec.signals = [
            np.asarray(x * gains[k], dtype=np.float32) for x, k in zip(rec.signals, session, strict=True)
        ]
    else:
        raise ValueError(name)
    return rec


DATASETS = (
    ("8 surfaces x 6 sessions (table 13-20), seed 5, session jitter 0.08", 5),
    ("5 surfaces x 7 sessions (table 21-25), seed 9, noise 3 LSB, jitter 0.12", 9),
    ("CSV 4 surfaces x 6 sessions, alike pair, +-15 % gain", 21),
    ("CSV 4 surfaces x 4 sessions, alike pair, +-15 % gain", 33),
)


def _write(rec, keep: np.ndarray, where: Path, csv: bool) -> list[Path]:
    from tactile_torch.robot.files.csv_logs import write_csv_recording
    from tactile_torch.robot.files.formats import RecordingArrays, write_recordings

    where.mkdir(parents=True, exist_ok=True)
    session = np.array([s.rsplit("/", 1)[1] for s in rec.session])
    idx = np.flatnonzero(keep)
    if csv:
        return [
            write_csv_recording(
                where / f"{rec.class_names[rec.labels[i]]}_{session[i]}.csv", rec.signals[i], rec.rate_hz
            )
            for i in idx
        ]
    arrays = RecordingArrays(
        signals=np.stack([rec.signals[i] for i in idx]),
        labels=np.asarray(rec.labels)[idx],
        class_names=tuple(rec.class_names),
        rate_hz=float(rec.rate_hz),
        session=session[idx],
    )
    return [write_recordings(where / "recordings.npz", arrays)]


def main() -> None:
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.tradeoff import run_tradeoff

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="runs/coverage")
    parser.add_argument("--only", type=int, default=None, help="only data set number N (0-based)")
    parser.add_argument(
        "--classifiers",
        type=lambda t: t.split(","),
        default=None,
        help="restrict the candidates (default: all of --quick), e.g. LDA,NCM,kNN to save ONNX exports",
    )
    parser.add_argument(
        "--windows",
        type=lambda t: [int(v) for v in t.split(",")],
        default=None,
        help="e.g. 800 (default: quick's)",
    )
    parser.add_argument(
        "--reverse",
        action="store_true",
        help="the cases in reverse order (a second process from the other end)",
    )
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = []
    plan = []  # (data set, held-out session), round robin over the data sets: every set early on
    prepared = {}
    for d, (name, seed) in enumerate(DATASETS):
        if args.only is not None and d != args.only:
            continue
        rec = _recordings(name, seed)
        session = np.array([s.rsplit("/", 1)[1] for s in rec.session])
        prepared[name] = (rec, session)
        plan.append([(name, held) for held in sorted(set(session), key=int)])
    order = [
        case for turn in range(max(map(len, plan))) for cases_of in plan for case in cases_of[turn : turn + 1]
    ]
    for name, held in reversed(order) if args.reverse else order:
        rec, session = prepared[name]
        csv = name.startswith("CSV")
        tmp = Path(tempfile.mkdtemp(prefix="coverage-"))
        try:
            train = _write(rec, session != held, tmp / "train", csv)
            test = _write(rec, session == held, tmp / "test", csv)
            start = time.perf_counter()
            result = run_tradeoff(
                train if csv else train[0],
                quick=True,
                windows=args.windows,
                classifiers=args.classifiers,
                out_dir=tmp / "out",
                progress=False,
                log=lambda s: None,
            )
            seconds = time.perf_counter() - start
            if result.recommended is None:
                cases.append({"data": name, "held_out": held, "recommended": None, "status": result.status})
                print(f"{name} | session {held}: no recommendation ({result.status})", flush=True)
                continue
            row = result.row(result.recommended)
            pipe = OnnxPipeline(tmp / "out" / "recommended.onnx")
            labelled = pipe.read_npz(test if csv else test[0])
            acc = float(np.mean(pipe.predict(labelled.raw) == labelled.labels))
            inside = row["accuracy_low"] - 1e-9 <= acc <= row["accuracy_high"] + 1e-9
            case = {
                "data": name,
                "held_out": held,
                "recommended": result.recommended,
                "unit": row["unit"],
                "n_units": row["n_units"],
                "interval": row["interval"],
                "mean": row["accuracy"],
                "low": row["accuracy_low"],
                "high": row["accuracy_high"],
                "held_out_accuracy": acc,
                "inside": bool(inside),
                "seconds": seconds,
            }
            cases.append(case)
            print(
                f"{name} | session {held}: {result.recommended}: {row['interval']} [{row['accuracy_low']:.3f}, "
                f"{row['accuracy_high']:.3f}] over {row['n_units']} {row['unit']}s; held out {acc:.3f} "
                f"{'inside' if inside else 'OUTSIDE'} ({seconds:.0f} s)",
                flush=True,
            )
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            (out / "coverage.json").write_text(json.dumps({"cases": cases}, indent=1) + "\n")
    summary = {}
    for kind in ("prediction", "range"):
        chosen = [c for c in cases if c.get("interval") == kind]
        if chosen:
            summary[kind] = {"cases": len(chosen), "inside": sum(c["inside"] for c in chosen)}
            share = summary[kind]["inside"] / len(chosen)
            print(
                f"{kind}: {summary[kind]['inside']} of {len(chosen)} held-out sessions inside ({share:.0%})"
            )
    doc = {
        "options": {"classifiers": args.classifiers, "windows": args.windows},
        "summary": summary,
        "cases": cases,
    }
    (out / "coverage.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
