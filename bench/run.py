"""Run the benchmarks (``make bench``) and write ``<name>.json``, ``<name>.md`` and ``summary.md`` to
``--out`` (default ``bench/results``, the committed results; ``tactile-torch bench`` defaults to
``runs/bench`` in the working directory instead).

A benchmark is a module ``bench/bench_<name>.py`` with ``TITLE`` and ``run(quick: bool) -> dict``
returning ``{"rows": [...], "notes": [...]}``; each row is one measured configuration (op, size,
threads, ours, reference, ratio ...).
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
if str(ROOT) not in sys.path:  # so that `python bench/run.py` finds bench.* and tests.reference_*
    sys.path.insert(0, str(ROOT))

from bench.common import machine  # noqa: E402


def discover() -> list[str]:
    """Return the benchmark names found as ``bench/bench_<name>.py``."""
    return sorted(p.stem.removeprefix("bench_") for p in (ROOT / "bench").glob("bench_*.py"))


def markdown_table(rows: list[dict], floatfmt: str = ".4g") -> str:
    """Render rows (dicts) as a markdown table."""
    columns = list(dict.fromkeys(k for row in rows for k in row))

    def cell(v: object) -> str:
        text = format(v, floatfmt) if isinstance(v, float) else str(v)
        return text.replace("|", "\\|")  # a '|' inside a cell would split it into two columns

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c, "")) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small sizes, for a smoke test")
    parser.add_argument("--only", default="", help="comma-separated benchmark names")
    parser.add_argument(
        "--out", type=Path, default=RESULTS, help="directory for the results (default: bench/results)"
    )
    args = parser.parse_args(argv)
    out = args.out
    names = discover()
    wanted = [n for n in args.only.split(",") if n] or names
    unknown = sorted(set(wanted) - set(names))
    if unknown:
        parser.error(f"--only must name benchmarks among {names}, got unknown {unknown}")
    if not names:
        print("no benchmarks exist yet (bench/bench_*.py)")
    out.mkdir(parents=True, exist_ok=True)
    env = machine()
    for name in wanted:
        module = importlib.import_module(f"bench.bench_{name}")
        print(f"[bench] {name}: {module.TITLE}", flush=True)
        start = time.perf_counter()
        result = module.run(quick=args.quick)
        record = {
            "name": name,
            "title": module.TITLE,
            "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "quick": args.quick,
            "command": f"make bench  # or: python bench/run.py --only {name}"
            + (" --quick" if args.quick else ""),
            "machine": env,
            "seconds": round(time.perf_counter() - start, 1),
            **result,
        }
        suffix = "-quick" if args.quick else ""
        (out / f"{name}{suffix}.json").write_text(json.dumps(record, indent=1) + "\n")
        md = [f"# {module.TITLE}", "", f"`{record['command']}` on {env}, {record['date']}", ""]
        md += [markdown_table(result["rows"]), ""] + [f"- {n}" for n in result.get("notes", [])]
        (out / f"{name}{suffix}.md").write_text("\n".join(md) + "\n")
        print(markdown_table(result["rows"]), flush=True)
    if not args.quick:
        summary = ["# Benchmark results", "", "Written by `make bench`. One file per benchmark:", ""]
        done = sorted(
            p.stem for p in out.glob("*.md") if p.stem != "summary" and not p.stem.endswith("-quick")
        )
        summary += [f"- [{n}]({n}.md)" for n in done]
        (out / "summary.md").write_text("\n".join(summary) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
