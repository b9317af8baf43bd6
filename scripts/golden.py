"""Golden set: the numbers every public route writes, recorded once and compared to the bit.

Runs the command line (the user's interface: its JSON and CSV outputs) on

* every packaged example problem (``morphoshell solve``),
* an ablation (toy problem 2, ``morphoshell ablate``),
* the inverse estimates of the synthetic ablation table (``morphoshell estimate``),
* a fit of the synthetic t01 midline by each method (``morphoshell fit``),
* a short campaign (two timepoints, two variants) and a sweep (``morphoshell sweep``),

keeps every number of their outputs (timings, dates, versions and paths left out) and
either records them (``record``) or compares them with a recording (``compare``): floats
must be equal to the bit, other values equal.  A refactoring that moves code but not
arithmetic leaves this set unchanged; ``compare`` prints each difference and exits 1.

Usage::

    python scripts/golden.py record  [--file tests/golden/golden.json.gz] [--only NAME ...]
    python scripts/golden.py compare [--file tests/golden/golden.json.gz] [--only NAME ...]

The recording holds the machine it was made on (:func:`machine`): round-off of BLAS and
compiled kernels may differ on another processor, so ``tests/test_golden.py`` compares
only on the same kind of machine.
"""
from __future__ import annotations

import argparse
import csv
import gzip
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_FILE = ROOT / "tests" / "golden" / "golden.json.gz"
EXAMPLES = ["toy1_sphere", "toy2_ablation", "toy3_anisotropic", "fast_relaxation",
            "volvox_inversion"]
T01 = ROOT / "data" / "synthetic_inversion" / "t01" / "synthetic_average.csv"

#: Keys whose values depend on the run, not on the arithmetic.
VOLATILE = {"time", "timing", "elapsed", "seconds", "wall_time", "created", "date", "version",
            "morphoshell_version", "provenance", "python", "platform", "path", "file", "data_dir",
            "out", "hostname", "casadi", "numpy", "scipy", "started", "finished", "duration",
            "wall_seconds", "solve_time", "t_wall", "t_proc", "sha256", "source"}


def cases(tmp: Path) -> dict[str, tuple[list[str], list[Path]]]:
    """Each case's command line (after ``morphoshell``) and the output files it writes."""
    out: dict[str, tuple[list[str], list[Path]]] = {}
    for name in EXAMPLES:
        problem = ROOT / "problems" / f"{name}.toml"
        j, c = tmp / f"solve_{name}.json", tmp / f"solve_{name}.csv"
        # one CSV of nodal arrays is enough to pin the writer: they repeat the JSON's
        csv_out = ["--csv", str(c)] if name == "toy2_ablation" else []
        out[f"solve_{name}"] = (["solve", str(problem), "--json", str(j), *csv_out],
                                [j, c] if csv_out else [j])
    j, c = tmp / "ablate.json", tmp / "ablate.csv"
    out["ablate_toy2"] = (["ablate", str(ROOT / "problems" / "toy2_ablation.toml"), "--set",
                           "k=-0.5", "--json", str(j), "--csv", str(c)], [j, c])
    j, c = tmp / "estimate.json", tmp / "estimate.csv"
    out["estimate"] = (["estimate", str(ROOT / "data" / "synthetic_ablations.csv"), "--bootstrap",
                        "200", "--workers", "1", "--json", str(j), "--csv", str(c)], [j, c])
    # Nelder-Mead with eight parameters held: all thirteen take a minute.
    held = [a for kv in ("f2=1.0", "f3=1.2", "f4=0.95", "f5=1.3", "kappa3=0.85", "kappa4=1.1",
                         "s3=1.97", "s4=2.4") for a in ("--set", kv)]
    for method in ("nelder-mead", "gradient", "kkt"):
        j, c = tmp / f"fit_{method}.json", tmp / f"fit_{method}.csv"
        out[f"fit_{method}"] = (["fit", str(T01), "--variant", "unstressed", "--method", method,
                                 "--nodes", "60", "--json", str(j), "--csv", str(c),
                                 *(held if method == "nelder-mead" else [])], [j, c])
    camp = tmp / "campaign"
    out["campaign"] = (["campaign", str(ROOT / "data" / "synthetic_inversion"), "--timepoints",
                        "t01,t02", "--variants", "flat,free", "--method", "gradient", "--nodes",
                        "60", "--workers", "1", "--out", str(camp)], [camp])
    j, c = tmp / "sweep.json", tmp / "sweep.csv"
    out["sweep"] = (["sweep", str(ROOT / "problems" / "toy2_ablation.toml"), "--set",
                     "k=-1:0.5:4", "--set", "h=0.2,0.3", "--nodes", "80", "--workers", "1",
                     "--json", str(j), "--csv", str(c)], [j, c])
    return out


def _volatile(key) -> bool:
    key = str(key).lower()
    return key in VOLATILE or "seconds" in key or "timing" in key


def _numbers(value, prefix: str, into: dict) -> None:
    """Flatten JSON into ``path -> value``, floats as their exact hex, volatile keys left out."""
    if isinstance(value, dict):
        for k, v in value.items():
            if not _volatile(k):
                _numbers(v, f"{prefix}/{k}", into)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _numbers(v, f"{prefix}[{i}]", into)
    elif isinstance(value, float):
        into[prefix] = value.hex() if math.isfinite(value) else repr(value)
    elif isinstance(value, str):
        # input files are named by path: the same wherever the repository is cloned
        into[prefix] = value.replace(str(ROOT), "<repository>")
    else:
        into[prefix] = value


def _csv_numbers(path: Path, prefix: str, into: dict) -> None:
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header = rows[0]
    for i, row in enumerate(rows[1:]):
        for key, cell in zip(header, row):
            if _volatile(key):
                continue
            try:
                into[f"{prefix}[{i}]/{key}"] = float(cell).hex()
            except ValueError:
                into[f"{prefix}[{i}]/{key}"] = cell.replace(str(ROOT), "<repository>")


def _collect(paths: list[Path], name: str) -> dict:
    into: dict = {}
    for path in paths:
        files = sorted(path.rglob("*")) if path.is_dir() else [path]
        for f in files:
            key = f"{name}:{f.relative_to(path.parent) if path.is_dir() else f.name}"
            if f.suffix == ".json":
                _numbers(json.loads(f.read_text()), key, into)
            elif f.suffix == ".csv":
                _csv_numbers(f, key, into)
    return into


def machine() -> dict[str, str]:
    """What the bits depend on besides the code: processor, Python and the numeric libraries."""
    import casadi
    import numpy
    import scipy

    model = ""
    try:
        model = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                     if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"machine": platform.machine(), "cpu": model, "python": platform.python_version(),
            "numpy": numpy.__version__, "scipy": scipy.__version__, "casadi": casadi.__version__}


def load(path: Path) -> dict:
    """A recording: ``{"machine": ..., "cases": {name: {key: value}}}``."""
    with gzip.open(path, "rt") as f:
        return json.load(f)


def run(only: list[str] | None = None) -> dict[str, dict]:
    """Run the cases (all, or those named) and return their numbers."""
    results = {}
    env = dict(os.environ, PYTHONHASHSEED="0")
    # the commands run in a temporary folder: a relative PYTHONPATH (PYTHONPATH=src) would
    # find nothing there, and they would run whatever morphoshell is installed instead
    if env.get("PYTHONPATH"):
        env["PYTHONPATH"] = os.pathsep.join(str(Path(p).resolve())
                                            for p in env["PYTHONPATH"].split(os.pathsep) if p)
    with tempfile.TemporaryDirectory() as d:
        for name, (argv, paths) in cases(Path(d)).items():
            if only and name not in only:
                continue
            proc = subprocess.run([sys.executable, "-m", "morphoshell.cli", "-q", *argv],
                                  cwd=d, env=env, capture_output=True, text=True)
            if proc.returncode != 0:
                raise SystemExit(f"{name}: exit {proc.returncode}\n{proc.stderr}")
            results[name] = _collect(paths, name)
            print(f"{name}: {len(results[name])} values", flush=True)
    return results


def compare(golden: dict[str, dict], now: dict[str, dict]) -> list[str]:
    """Differences between two recordings, one line each (empty: equal to the bit)."""
    lines = []
    for name, values in now.items():
        old = golden.get(name)
        if old is None:
            lines.append(f"{name}: not in the golden set")
            continue
        for key in sorted(set(old) | set(values)):
            a, b = old.get(key, "<missing>"), values.get(key, "<missing>")
            if a != b:
                lines.append(f"{key}: {_show(a)} -> {_show(b)}")
    return lines


def _show(v):
    try:
        return repr(float.fromhex(v)) if isinstance(v, str) and v.startswith(("0x", "-0x")) else v
    except ValueError:
        return v


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("action", choices=["record", "compare"])
    p.add_argument("--file", type=Path, default=DEFAULT_FILE)
    p.add_argument("--only", nargs="*", help="case names (default: all)")
    a = p.parse_args(argv)
    now = run(a.only)
    if a.action == "record":
        a.file.parent.mkdir(parents=True, exist_ok=True)
        if a.only and a.file.exists():    # (the other cases as recorded: --only used to drop them)
            now = {**load(a.file)["cases"], **now}
        text = json.dumps({"machine": machine(), "cases": now}, indent=0, sort_keys=True)
        a.file.write_bytes(gzip.compress(text.encode(), mtime=0))    # the same bytes each time
        print(f"recorded {sum(map(len, now.values()))} values in {a.file}")
        return 0
    golden = load(a.file)
    if golden["machine"] != machine():
        print(f"note: recorded on {golden['machine']}, running on {machine()}")
    diffs = compare(golden["cases"], now)
    for line in diffs[:200]:
        print(line)
    n = sum(map(len, now.values()))
    print(f"{len(diffs)} of {n} values differ from {a.file}" if diffs
          else f"all {n} values equal to the bit")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
