"""Bad inputs of ``estimate``, ``fit``, ``campaign`` and ``ablate`` for tests/test_fuzz.py.

:func:`make_bad_files` writes the bad files once (binary, empty, wrong delimiter, NaN rows,
too few points, missing columns, folders where files belong ...); :func:`bad_inputs` draws a
command line from them and from bad option values, with the text its one-line refusal must
contain.  Every case is refused by a check that runs before any solver: the property in
tests/test_fuzz.py also bounds its time.  (Unreadable files are not drawn: the tests may run
as root, which reads any file.)
"""
from __future__ import annotations

import math
from pathlib import Path

from hypothesis import strategies as st

from morphoshell.workflows.campaigns import CAMPAIGN_NODES

ROOT = Path(__file__).resolve().parents[1]
TABLE = str(ROOT / "data" / "synthetic_ablations.csv")
DATA_DIR = ROOT / "data" / "synthetic_inversion"
MIDLINE = str(DATA_DIR / "t01" / "synthetic_average.csv")

_HEADER = "embryo,R_um,H_um,hole_diameter_um,opening_um,rotation_deg,displacement_um"
_ROW = "A,40,11,8,0.5,15,1.5"

#: Bad measurement tables (estimate): file name → content.
TABLES = {
    "empty.csv": "",
    "header_only.csv": _HEADER + "\n",
    "semicolons.csv": _HEADER.replace(",", ";") + "\n" + _ROW.replace(",", ";") + "\n",
    "nan_row.csv": f"{_HEADER}\n{_ROW}\nB,nan,11,8,0.5,15,1.5\n",
    "missing_column.csv": "embryo,R_um,H_um,hole_diameter_um,opening_um,displacement_um\n"
                          "A,40,11,8,0.5,1.5\n",
    "short_row.csv": f"{_HEADER}\nA,40,11\n",
    "negative_H.csv": f"{_HEADER}\nA,40,-11,8,0.5,15,1.5\n",
    "thick.csv": f"{_HEADER}\nA,40,41,8,0.5,15,1.5\n",
    "big_hole.csv": f"{_HEADER}\nA,40,11,81,0.5,15,1.5\n",
    "rotation_180.csv": f"{_HEADER}\nA,40,11,8,0.5,180,1.5\n",
    "twice.csv": f"{_HEADER}\n{_ROW}\n{_ROW}\n",
    "inf_opening.csv": f"{_HEADER}\nA,40,11,8,inf,15,1.5\n",
    "huge_opening.csv": f"{_HEADER}\nA,40,11,8,1e308,15,1.5\n",
    "huge_radius.csv": f"{_HEADER}\nA,1e300,11,8,0.5,15,1.5\n",
    "words.csv": f"{_HEADER}\nA,forty,11,8,0.5,15,1.5\n",
}

#: Bad midlines (fit; campaign's timepoints name them too).
MIDLINES = {
    "empty_mid.csv": "",
    "two_points.csv": "r,z\n0,0\n0.5,0.1\n",
    "nan_mid.csv": "r,z\n0,0\nnan,0.1\n0.5,0.2\n0.7,0.3\n",
    "semicolon_mid.csv": "r;z\n0;0\n0.2;0.1\n0.5;0.2\n0.7,0.3\n",
    "one_column.csv": "r\n0\n0.2\n0.5\n0.7\n",
    "words_mid.csv": "r,z\n0,0\n0.2,abc\n0.5,0.2\n0.7,0.3\n",
    "inf_mid.csv": "r,z\n0,0\n0.2,inf\n0.5,0.2\n0.7,0.3\n",
}

#: Bad timepoints.csv (campaign): folder name → content.
TIMEPOINTS = {
    "tp_empty": "",
    "tp_header_only": "timepoint,pseudotime,midline\n",
    "tp_missing_column": "timepoint,midline\nt01,t01/m.csv\n",
    "tp_nan_time": "timepoint,pseudotime,midline\nt01,nan,m.csv\n",
    "tp_words_time": "timepoint,pseudotime,midline\nt01,soon,m.csv\n",
    "tp_no_midline": "timepoint,pseudotime,midline\nt01,0,nothing_here.csv\n",
    "tp_twice": "timepoint,pseudotime,midline\nt01,0,m.csv\nt01,1,m.csv\n",
    "tp_backwards": "timepoint,pseudotime,midline\nt01,1,m.csv\nt02,0,m.csv\n",
    "tp_semicolons": "timepoint;pseudotime;midline\nt01;0;m.csv\n",
    "tp_bad_name": "timepoint,pseudotime,midline\nt 01/..,0,m.csv\n",
    "tp_two_points": "timepoint,pseudotime,midline\nt01,0,two_points.csv\n",
    "tp_midline_folder": "timepoint,pseudotime,midline\nt01,0,sub\n",
}

#: Bad problem files (ablate).
PROBLEMS = {
    "garbage.toml": "[[[problem",
    "empty.toml": "",
    "no_family.toml": "[problem]\nh = 0.1\n",
    "truncated.json": '{"problem": {"family": "uniform", "h": 0.1',
    "list.json": "[1, 2, 3]",
    "fit_not_problem.json": '{"E_fit": 0.1, "parameters": {}}',
}


def make_bad_files(tmp: Path) -> None:
    """Write every bad file and folder of the strategies below into ``tmp``."""
    for name, text in {**TABLES, **MIDLINES, **PROBLEMS}.items():
        (tmp / name).write_text(text)
    for name in ("binary.csv", "binary.toml", "binary.json", "binary.roi"):
        (tmp / name).write_bytes(bytes([0xCE, 0x00, 0xFF, 0x10]) * 64)
    (tmp / "a_folder.csv").mkdir()
    (tmp / "a_file").write_text("x")
    good = (DATA_DIR / "t01" / "synthetic_average.csv").read_text()
    for name, text in TIMEPOINTS.items():
        folder = tmp / name
        folder.mkdir()
        (folder / "m.csv").write_text(good)
        (folder / "two_points.csv").write_text(MIDLINES["two_points.csv"])
        (folder / "sub").mkdir()
        (folder / "timepoints.csv").write_text(text)
    (tmp / "tp_binary").mkdir()
    (tmp / "tp_binary" / "timepoints.csv").write_bytes(bytes([0xCE, 0x00, 0xFF, 0x10]) * 64)
    (tmp / "tp_none").mkdir()


# --------------------------------------------------------------------------
# bad option values shared by the commands
# --------------------------------------------------------------------------

_NOT_NUMBER = ["abc", "", " ", "nan", "inf", "-inf", "1e400", "-1e400", "0x10", "1,5", "--"]
_NOT_INT = ["abc", "1.5", "1e3", "", "nan", "-", "0x10", "5.0", "inf"]


def _number(bad_extra: list[str], lo: float = 0.0, hi: float = 1e6) -> st.SearchStrategy[str]:
    """A value that is not a number in (lo, hi]: a non-number, one of ``bad_extra``, or a
    float outside (NaN, infinities, huge and tiny magnitudes of either sign included)."""
    outside = st.one_of(st.floats(max_value=lo), st.floats(min_value=hi, exclude_min=True),
                        st.sampled_from([math.nan, math.inf, -math.inf, -5e-324, 1e308]))
    return st.one_of(st.sampled_from([*_NOT_NUMBER, *bad_extra]), outside.map(repr))


def _integer(lo: int, hi: int) -> st.SearchStrategy[str]:
    """A value that is not an integer in [lo, hi]."""
    return st.one_of(st.sampled_from(_NOT_INT), st.integers(-10**12, lo - 1).map(str),
                     st.integers(hi + 1, 10**15).map(str))


def _typo(choices: list[str]) -> st.SearchStrategy[str]:
    """A choice misspelt: another case, a letter dropped or doubled, or nonsense."""
    return st.sampled_from(choices).flatmap(lambda c: st.sampled_from(
        [c.upper(), c[:-1], c + c[-1], c.replace("-", "_") if "-" in c else c + "-", "x", ""]))


def _output(tmp: Path, draw) -> tuple[list[str], str]:
    """A bad --json/--csv/--plot path (in a missing folder, a file, the wrong suffix ...)."""
    option = draw(st.sampled_from(["--json", "--csv", "--plot"]))
    suffix = {"--json": ".json", "--csv": ".csv", "--plot": ".png"}[option]
    path = draw(st.sampled_from([f"{tmp}/no/such/dir/out{suffix}", f"{tmp}/out.txt", str(tmp),
                                 "", f"{tmp}/a_file/out{suffix}"]))
    return [option, path], option


# --------------------------------------------------------------------------
# one strategy per command: (argv, the text the refusal must contain)
# --------------------------------------------------------------------------

#: 2/h of the table's thickest shell (h = 0.335): the largest |k| a k-range may reach.
_K_LIMIT = 5.963


def _wide_k_range() -> st.SearchStrategy[tuple[str, str]]:
    """A k-range within the parser's [-100, 100] that reaches |k| >= 2/h of a shell."""
    far = st.floats(_K_LIMIT, 100.0)
    return st.one_of(
        st.tuples(far.map(lambda v: -v), st.floats(-_K_LIMIT + 0.01, _K_LIMIT - 0.01)),
        st.tuples(st.floats(-_K_LIMIT + 0.01, _K_LIMIT - 0.01), far),
        st.sampled_from([(-100.0, 100.0), (-9.0, -8.9), (6.0, 7.0)]),
    ).map(lambda pair: tuple(repr(v) for v in pair))


def _estimate(draw, tmp: Path) -> tuple[list[str], str]:
    kind = draw(st.sampled_from(["file", "k-range", "mu-min", "bootstrap", "seed", "nodes",
                                 "workers", "theory", "output", "wide k-range"]))
    if kind == "file":
        name = draw(st.sampled_from([*TABLES, "binary.csv", "a_folder.csv", "missing.csv",
                                     "a_file"]))
        return ["estimate", f"{tmp}/{name}"], name
    args, named = {
        "k-range": lambda: (["--k-range", *draw(st.sampled_from(
            [("1", "0"), ("0", "0"), ("0", "nan"), ("-inf", "1"), ("x", "1"), ("-1e9", "1"),
             ("0", "1e400"), ("1", "101"), ("-1e-9", "-1e-9")]))], "--k-range"),
        "wide k-range": lambda: (["--k-range", *draw(_wide_k_range())], "--k-range"),
        "mu-min": lambda: (["--mu-min", draw(_number(["0", "-1", "-1e-300", "1e7"]))],
                           "--mu-min"),
        "bootstrap": lambda: (["--bootstrap", draw(_integer(0, 1_000_000))], "--bootstrap"),
        "seed": lambda: (["--seed", draw(_integer(0, 2**32 - 1))], "--seed"),
        "nodes": lambda: (["--nodes", draw(_integer(20, 3200))], "--nodes"),
        "workers": lambda: (["--workers", draw(_integer(1, 256))], "--workers"),
        "theory": lambda: (["--theory", draw(_typo(["large_bending", "classical"]))],
                           "--theory"),
        "output": lambda: _output(tmp, draw),
    }[kind]()
    return ["estimate", TABLE, *args], named


_BAD_HOLD = [("kappa5", "1", "kappa5"), ("F1", "1", "F1"), ("f1", "x", "f1"),
             ("f1", "nan", "f1"), ("f1", "inf", "f1"), ("f1", "1e400", "f1"),
             ("f1", "0", "f1"), ("f1", "-1", "f1"), ("kappa2", "1e308", "kappa2"),
             ("s1", "-1", "s1"), ("h", "0", "h"), ("h", "-0.1", "h"), ("h", "1e308", "h"),
             ("opening", "1e9", "opening"), ("opening", "nan", "opening"), ("k", "1", "'k'"),
             ("", "1", "--set"), ("h", "", "h")]


def _bad_hold() -> st.SearchStrategy[tuple[str, str, str]]:
    """(name, value, named) of a bad --set of fit: listed, or a number out of its range."""
    def outside(lo: float, hi: float) -> st.SearchStrategy[float]:
        return st.one_of(st.floats(max_value=lo, exclude_max=True),
                         st.floats(min_value=hi, exclude_min=True))
    drawn = st.one_of(
        st.tuples(st.sampled_from(["f1", "f2", "f3", "f5"]), outside(0.1, 10.0)),
        st.tuples(st.sampled_from(["kappa2", "kappa3", "kappa4"]), outside(-1e3, 1e3)),
        st.tuples(st.just("h"), outside(1e-6, 1.0 - 1e-16)))
    return st.one_of(st.sampled_from(_BAD_HOLD),
                     drawn.map(lambda nv: (nv[0], repr(nv[1]), nv[0])))


def _fit(draw, tmp: Path) -> tuple[list[str], str]:
    kind = draw(st.sampled_from(["file", "variant", "method", "format", "section", "pixel-size",
                                 "radius-um", "nodes", "set", "start", "profile",
                                 "profile-points", "output"]))
    variant = ["--variant", "flat"]
    if kind == "file":
        name = draw(st.sampled_from([*MIDLINES, "binary.csv", "binary.roi", "a_folder.csv",
                                     "missing.csv"]))
        return ["fit", f"{tmp}/{name}", *variant], name
    if kind == "variant":
        return ["fit", MIDLINE, "--variant", draw(_typo(["flat", "undeformed", "unstressed",
                                                         "free"]))], "--variant"
    if kind == "set":
        name, value, named = draw(_bad_hold())
        return ["fit", MIDLINE, *variant, "--set", f"{name}={value}"], named
    if kind == "start":
        name = draw(st.sampled_from(["binary.json", "truncated.json", "missing.json", "a_file",
                                     "garbage.toml", "a_folder.csv"]))
        if draw(st.booleans()) and name == "a_file":
            return ["fit", MIDLINE, *variant, "--start",
                    str(ROOT / "src/morphoshell/examples/toy2_ablation.toml")], "not volvox"
        return ["fit", MIDLINE, *variant, "--start", f"{tmp}/{name}"], name
    args, named = {
        "method": lambda: (["--method", draw(_typo(["nelder-mead", "gradient", "kkt"]))],
                           "--method"),
        "format": lambda: (["--format", draw(_typo(["csv", "xy", "fiji-xy", "roi"]))],
                           "--format"),
        "section": lambda: (["--section", draw(_typo(["auto", "whole", "half"]))], "--section"),
        "pixel-size": lambda: (["--pixel-size", draw(_number(["0", "-0.3", "1e7"]))],
                               "--pixel-size"),
        "radius-um": lambda: (["--radius-um", draw(_number(["0", "-40", "1e300"]))],
                              "--radius-um"),
        "nodes": lambda: (["--nodes", draw(_integer(20, 3200))], "--nodes"),
        "profile": lambda: (["--profile", draw(st.sampled_from(["kappa5", "F1", ",", "h",
                                                                "kappa1"]))], "--profile"),
        "profile-points": lambda: (["--profile", "f1", "--profile-points",
                                    draw(_integer(2, 1000))], "--profile-points"),
        "output": lambda: _output(tmp, draw),
    }[kind]()
    return ["fit", MIDLINE, *variant, *args], named


#: What a refusal of a timepoints folder names when the table refers to a bad file: the file.
_NAMED = {"tp_two_points": "two_points.csv", "tp_no_midline": "nothing_here.csv",
          "tp_midline_folder": "sub"}


def _campaign(draw, tmp: Path) -> tuple[list[str], str]:
    kind = draw(st.sampled_from(["folder", "variants", "method", "nodes", "workers",
                                 "held-from", "embryo-errors", "out", "timepoints"]))
    out = ["--out", f"{tmp}/campaign_out"]
    if kind == "folder":
        name = draw(st.sampled_from([*TIMEPOINTS, "tp_binary", "tp_none", "missing_dir",
                                     "a_file"]))
        return ["campaign", f"{tmp}/{name}", *out], _NAMED.get(name, name)
    if kind == "out":
        path = draw(st.sampled_from([f"{tmp}/a_file", f"{tmp}/no/such/dir", ""]))
        return ["campaign", str(DATA_DIR), "--out", path], "--out"
    args, named = {
        "variants": lambda: (["--variants", draw(st.one_of(
            _typo(["flat", "undeformed", "unstressed", "free"]),
            st.sampled_from(["flat,flat", ",", "flat;free"])))], "--variants"),
        "method": lambda: (["--method", draw(_typo(["nelder-mead", "gradient", "kkt"]))],
                           "--method"),
        # (the campaign's range, not a copy of it: it grew to the fit's, and 2002 ran)
        "nodes": lambda: (["--nodes", draw(_integer(*CAMPAIGN_NODES))], "--nodes"),
        "workers": lambda: (["--workers", draw(_integer(1, 4096))], "--workers"),
        "held-from": lambda: (["--held-from", draw(_typo(["flat", "undeformed", "free"]))],
                              "--held-from"),
        "embryo-errors": lambda: (["--embryo-errors", draw(st.one_of(
            _typo(["flat", "free"]), st.just("free")))], "--embryo-errors"),
        "timepoints": lambda: (["--timepoints", draw(st.sampled_from(
            ["t99", "t01,t99", ",", "t01,,t02", "T01"]))], "--timepoints"),
    }[kind]()
    if args[0] == "--embryo-errors":
        args += ["--variants", "flat"]    # errors of a variant not run
    return ["campaign", str(DATA_DIR), *out, *args], named


_BAD_PROBLEM_SET = [
    ("kappa", "1", "kappa"), ("hh", "1", "hh"), ("k", "abc", "k"), ("k", "nan", "k"),
    ("k", "inf", "k"), ("k", "1e400", "k"), ("k", "1e4", "k"), ("h", "0", "h"),
    ("h", "-1", "h"), ("h", "1", "h"), ("h", "1e308", "h"), ("h", "1e-9", "h"),
    ("cut", "0", "cut"), ("cut", "-0.1", "cut"), ("cut", "3.1413", "cut"), ("cut", "1e9", "cut"),
    ("opening", "1e308", "opening"), ("nodes", "0", "nodes"), ("nodes", "1e9", "nodes"),
    ("stages", "4", "stages"), ("method", "shoot", "method"), ("theory", "x", "theory"),
    ("family", "x", "family"), ("", "1", "--set"), ("k", "", "k")]


def _ablate(draw, tmp: Path) -> tuple[list[str], str]:
    from morphoshell.io.problem_files import example_path

    toy2 = str(example_path("toy2_ablation"))
    kind = draw(st.sampled_from(["file", "set", "method", "nodes", "stages", "rtol",
                                 "direct only", "output"]))
    if kind == "file":
        name = draw(st.sampled_from([*PROBLEMS, "binary.toml", "binary.json", "a_folder.csv",
                                     "missing.toml"]))
        return ["ablate", f"{tmp}/{name}"], name
    if kind == "set":
        name, value, named = draw(st.sampled_from(_BAD_PROBLEM_SET))
        return ["ablate", toy2, "--set", f"{name}={value}"], named
    args, named = {
        "method": lambda: (["--method", draw(_typo(["direct", "bvp", "shooting"]))],
                           "--method"),
        "nodes": lambda: (["--nodes", draw(_integer(5, 102400))], "--nodes"),
        "stages": lambda: (["--stages", draw(st.sampled_from(["0", "4", "2.0", "x"]))],
                           "--stages"),
        "rtol": lambda: (["--rtol", draw(_number(["0", "1", "-1e-6", "2", "1e-14"],
                                                 hi=1.0 - 1e-16))], "--rtol"),
        "direct only": lambda: (["--method", draw(st.sampled_from(["bvp", "shooting"])),
                                 *draw(st.sampled_from([["--rtol", "1e-6"],
                                                        ["--no-continuation"]]))],
                                "options of the direct method"),
        "output": lambda: _output(tmp, draw),
    }[kind]()
    return ["ablate", toy2, *args], named


#: Two image traces of one stage (pixels) and their radii in µm, for `average`.
_PIXEL_TRACES = [str(DATA_DIR / "t02" / f"synthetic_embryo{k}.csv") for k in (1, 2)]
_PIXEL_SCALE = ["--pixel-size", "0.3", "--section", "whole"]


def _average(draw, tmp: Path) -> tuple[list[str], str]:
    kind = draw(st.sampled_from(["file", "format", "section", "pixel-size", "radius-um",
                                 "radii", "roi", "traces", "output"]))
    radius = ["--radius-um", "41.7078,42.8509"]
    if kind == "file":
        name = draw(st.sampled_from([*MIDLINES, "binary.csv", "binary.roi", "a_folder.csv",
                                     "missing.csv"]))
        return ["average", MIDLINE.replace("synthetic_average", "synthetic_embryo1_midline"),
                f"{tmp}/{name}"], name
    args, named = {
        "format": lambda: (["--format", draw(_typo(["csv", "xy", "fiji-xy", "roi"]))],
                           "--format"),
        "section": lambda: (["--section", draw(_typo(["auto", "whole", "half"]))], "--section"),
        "pixel-size": lambda: (["--pixel-size", draw(_number(["0", "-0.3", "1e7"])), *radius],
                               "--pixel-size"),
        "radius-um": lambda: (["--pixel-size", "0.3", "--radius-um",
                               draw(_number(["0", "-40", "1e300"]))], "--radius-um"),
        "radii": lambda: (["--pixel-size", "0.3", "--radius-um",
                           draw(st.sampled_from(["40,41,42", "40,", ",", "40,,41"]))],
                          "--radius-um"),
        "roi": lambda: (["--pixel-size", "0.3", *radius, "--roi",
                         draw(st.sampled_from(["", "1"]))], "--roi"),
        "traces": lambda: ([*_PIXEL_SCALE, *radius, "--traces"], "--traces"),
        "output": lambda: _output(tmp, draw),
    }[kind]()
    return ["average", *_PIXEL_TRACES, *args], named


@st.composite
def bad_inputs(draw, tmp: Path) -> tuple[list[str], str]:
    """A bad command line of estimate, fit, average, campaign or ablate, and the text its
    refusal names."""
    command = draw(st.sampled_from([_estimate, _fit, _average, _campaign, _ablate]))
    return command(draw, tmp)


# --------------------------------------------------------------------------
# running one case
# --------------------------------------------------------------------------

class Hang(BaseException):
    """A case that ran past its time bound (a BaseException: ``main`` does not catch it)."""


def _alarm(signum, frame):
    raise Hang()


#: Warnings a user does not see (Python's default filters hide them outside ``__main__``).
_HIDDEN = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def run_cli(argv: list[str], limit: float) -> tuple[int, str, float, list[str]]:
    """Run ``morphoshell ARGV`` in this process, stopped after ``limit`` seconds.

    Returns
    -------
    (status, stderr, seconds, warnings)
        The exit status; everything written to standard error, by Python and by C
        libraries (file descriptor 2: CasADi's and Ipopt's messages); the seconds
        taken; the warnings a user would have seen.
    """
    import contextlib
    import io
    import os
    import signal
    import sys
    import tempfile
    import time
    import warnings

    from morphoshell.cli import main

    err = io.StringIO()
    with tempfile.TemporaryFile() as raw:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(raw.fileno(), 2)
        previous = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, limit)
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught, \
                    contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                warnings.simplefilter("default")
                status = main(argv)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
            os.dup2(saved, 2)
            os.close(saved)
        seconds = time.perf_counter() - t0
        raw.seek(0)
        text = raw.read().decode(errors="replace") + err.getvalue()
    shown = [f"{w.category.__name__}: {w.message}" for w in caught
             if not issubclass(w.category, _HIDDEN)]
    return status, text, seconds, shown
