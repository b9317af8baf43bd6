"""``morphoshell continue``: the issue's shell (tests/data/volvox_fold.toml, 400 nodes), whose
path from the stress-free parameters folds at lambda = 0.8723 and snaps through."""
import csv
import json
import re
from pathlib import Path

import pytest

from morphoshell.cli import main
from morphoshell.io.problem_files import example_path

FOLD = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"
RIM = (0.3903, 0.4629)          # the cold solve's rim at lambda = 1 (issue 38)
COLUMNS = ["lambda", "energy", "r_end", "z_end", "psi_end", "stable", "negative_eigenvalues",
           "event", "lambda_error", "energy_error", "r_end_error", "z_end_error", "psi_end_error"]


@pytest.fixture(scope="module")
def neutral(tmp_path_factory):
    """`continue --from neutral` on the issue's shell: its CSV rows, JSON, stdout."""
    folder = tmp_path_factory.mktemp("continue")
    paths = {k: folder / f"branch.{k}" for k in ("csv", "json", "png")}
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(["continue", str(FOLD), "--from", "neutral",
                       *(a for k, p in paths.items() for a in (f"--{'plot' if k == 'png' else k}",
                                                               str(p)))])
    with paths["csv"].open() as fh:
        rows = list(csv.DictReader(fh))
    return status, rows, json.loads(paths["json"].read_text()), out.getvalue(), paths


def test_the_issue_shell_folds_goes_unstable_and_ends_stable_at_the_cold_solve(neutral):
    status, rows, _, stdout, _ = neutral
    assert status == 0
    assert list(rows[0]) == COLUMNS
    folds = [r for r in rows if r["event"] == "fold"]
    first = float(folds[0]["lambda"])
    assert 0.868 <= first <= 0.876, first
    after = rows[rows.index(folds[0]) + 1]
    assert after["stable"] == "false" and int(after["negative_eigenvalues"]) >= 1
    before = rows[rows.index(folds[0]) - 1]
    assert before["stable"] == "true" and before["negative_eigenvalues"] == "0"
    end = rows[-1]
    assert float(end["lambda"]) == 1.0 and end["stable"] == "true"
    assert abs(float(end["r_end"]) - RIM[0]) < 1e-3 and abs(float(end["z_end"]) - RIM[1]) < 1e-3
    assert {r["stable"] for r in rows} == {"true", "false"}
    assert {r["event"] for r in rows} <= {"", "fold", "branch_point", "snap"}
    assert f"fold          at lambda = {first:.10g}" in stdout and "end at lambda = 1: stable" \
        in stdout
    # the end's error estimate, as solve()'s (audit 22 F5): its line, its row only
    assert re.search(r"end at lambda = 1: stable, .* C R\^2; error estimate .* \(vs 200 nodes, "
                     r"order 4\)", stdout)
    assert 0 < float(end["z_end_error"]) < 1e-5 and 0 < float(end["energy_error"]) < 1e-7
    assert all(r[k] == "" for r in rows[:-1] for k in COLUMNS[-4:])


def test_json_and_plot(neutral):
    _, rows, doc, _, paths = neutral
    assert doc["points"]["lambda"] == [float(r["lambda"]) for r in rows]
    assert doc["parameter"] is None and doc["follow"] == "branch" and "morphoshell" in doc
    from morphoshell.io.problem_files import load_problem
    from morphoshell.solvers.paths import ParameterLine, neutral_problem

    problem, _ = load_problem(FOLD)
    line = ParameterLine.between(neutral_problem(problem), problem)
    assert doc["path"] == {n: [a, b] for n, a, b in zip(line.names, line.a, line.b)}
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_one_parameter_has_its_own_column(tmp_path):
    out = tmp_path / "h.csv"
    assert main(["continue", str(FOLD), "--param", "h", "--to", "0.13", "--nodes", "100",
                 "--csv", str(out)]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["lambda", "h", *COLUMNS[1:]]
    assert float(rows[0]["h"]) == 0.15 and float(rows[-1]["h"]) == pytest.approx(0.13, abs=1e-15)
    for r in rows:      # the parameter's column is the path's
        assert float(r["h"]) == pytest.approx(0.15 + float(r["lambda"]) * (0.13 - 0.15),
                                              abs=1e-14)


def test_the_path_ends_exactly_at_the_target_with_units(tmp_path):
    """0.3 + 1 (0.01 - 0.3) = 0.010000000000000009: the last row said so (user audit); the
    JSON had no units, as a sweep's has."""
    paths = {k: tmp_path / f"h.{k}" for k in ("csv", "json")}
    assert main(["continue", str(example_path("toy2_ablation")), "--param", "h", "--to", "0.01",
                 "--nodes", "60", "--csv", str(paths["csv"]), "--json", str(paths["json"])]) == 0
    with paths["csv"].open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows[-1]["lambda"] == "1.0" and rows[-1]["h"] == "0.01" and rows[0]["h"] == "0.3"
    doc = json.loads(paths["json"].read_text())
    assert doc["points"]["h"][-1] == 0.01
    assert doc["units"] == {"lambda": "1", "h": "R", "energy": "C R^2", "r_end": "R",
                            "z_end": "R", "psi_end": "rad", "negative_eigenvalues": "1",
                            "lambda_error": "1", "energy_error": "C R^2", "r_end_error": "R",
                            "z_end_error": "R", "psi_end_error": "rad"}


@pytest.mark.parametrize("to", ["0.001", "0.5"])
def test_a_path_to_an_end_of_the_parameters_range_lands_on_it(to, tmp_path, capsys):
    """sigma's range is [0.001, 0.5], closed: --to at either bound failed after the walk's
    work, exit 2 as bad input naming sigma = 0.000985 (or 0.504), a value never given (audit
    17): the step past the end was evaluated there.  It is shortened to land on the end."""
    out = tmp_path / "s.csv"
    assert main(["continue", str(FOLD), "--param", "sigma", "--to", to, "--nodes", "40",
                 "--csv", str(out)]) == 0, capsys.readouterr().err
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows[-1]["lambda"] == "1.0" and rows[-1]["sigma"] == to
    sigmas = [float(r["sigma"]) for r in rows]
    assert all(0.001 <= v <= 0.5 for v in sigmas) and len(rows) > 10


@pytest.mark.parametrize("args, named", [
    (["--param", "h"], "--param and --to go together"),
    (["--to", "0.2"], "--param and --to go together"),
    (["--param", "hh", "--to", "1"], "unknown parameter 'hh'"),
    (["--param", "h", "--to", "0.15"], "h is already 0.15"),
    (["--param", "cut", "--to", "0.3"], "cannot take cut from 0.0 to 0.3"),
    (["--param", "h", "--to", "2"], "thickness h"),
    (["--nodes", "2"], "--nodes"),
    (["--follow", "sideways"], "--follow"),
    (["--max-step", "0"], "--max-step"),
    # audit 26, F7: it said "must be a finite number in [-inf, inf]"
    (["--param", "h", "--to", "nan"], "argument --to: nan must be a finite number (see "),
    # a user audit: --from was ignored with --param, exit 0
    (["--from", "neutral", "--param", "h", "--to", "0.2"], "--from neutral and --param h are "
                                                           "two paths"),
    # audit 26, F5: a reference route was run as the direct one (a note), sweep refused it
    (["--set", "method=bvp"], f"{FOLD}: method = 'bvp': continuations use the direct method"),
    (["--set", "method=shooting", "--param", "h", "--to", "0.2"],
     "method = 'shooting': continuations use the direct method"),
])
def test_bad_input_exits_2_with_one_line_and_no_output(args, named, tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["continue", str(FOLD), *args, "--csv", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err, err
    assert not out.exists()


def test_very_verbose_lists_every_step(tmp_path, capsys):
    """-vv shows each pseudo-arclength step: lambda, the parameters, the step size, Newton
    iterations and the inertia (a user audit: the README promised them, none came).  Each
    ordinary point of the CSV but the first (the start) is an accepted step's."""
    out = tmp_path / "x.csv"
    assert main(["continue", str(FOLD), "--nodes", "40", "--csv", str(out), "-vv"]) == 0
    steps = [line for line in capsys.readouterr().err.splitlines()
             if line.startswith("morphoshell [branches]: lambda = ")]
    assert re.fullmatch(r"morphoshell \[branches\]: lambda = \S+: step \S+, "
                        r"\d+ Newton iterations, \d+ negative and \d+ zero eigenvalues", steps[0])
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(steps) >= sum(row["event"] == "" for row in rows) - 1


def test_a_branch_that_runs_out_of_points_exits_3_and_writes_its_part_marked(tmp_path,
                                                                          capsys):
    """The branch up to an early stop (here --max-points) is a result: it was lost, 2000
    points and their folds (audit 14).  It is written, marked partial with why (the CSV's
    first line, the JSON's complete/ended), the message names the files, the status is
    still 3."""
    out, doc = tmp_path / "x.csv", tmp_path / "x.json"
    assert main(["continue", str(FOLD), "--nodes", "100", "--max-points", "5",
                 "--csv", str(out), "--json", str(doc)]) == 3
    err = capsys.readouterr().err
    # the cause is known: the remedy is --max-points, not "a cusp or a branch point?" (audit)
    assert "Branch_Ended" in err and "raise max_points (--max-points)" in err
    assert "cusp" not in err
    assert f"the 5 points followed to lambda = " in err
    assert f"are kept in {doc} and {out}, marked partial" in err
    head = out.read_text().splitlines()[0]
    assert head.startswith("# morphoshell continue PARTIAL: the branch stopped early: the "
                           "branch ended at") and "raise max_points" in head
    import pandas as pd
    assert len(pd.read_csv(out, comment="#")) == 5
    data = json.loads(doc.read_text())
    assert data["complete"] is False and "the points ran out" in data["ended"]["why"]
    assert len(data["points"]["lambda"]) == 5


@pytest.mark.parametrize("sig, status, word", [
    ("SIGINT", 130, "interrupted"), ("SIGTERM", 143, r"terminated \(SIGTERM\)")])
def test_an_interrupted_branch_writes_the_points_followed_marked_partial(
        tmp_path, capsys, monkeypatch, sig, status, word):
    """Ctrl-C or SIGTERM (the real signal, after 6 points) during the walk: the points
    followed are written, marked partial, the one-line message names the files, and the
    exit status is the interruption's (130, 143); nothing had been written (audit 14)."""
    import os
    import signal

    from morphoshell.solvers import branches

    real, calls = branches._Walk.record, []

    def record(walk, *args, **kwargs):
        real(walk, *args, **kwargs)
        calls.append(1)
        if len(calls) == 6:
            os.kill(os.getpid(), getattr(signal, sig))

    monkeypatch.setattr(branches._Walk, "record", record)
    out, doc = tmp_path / "i.csv", tmp_path / "i.json"
    assert main(["continue", str(FOLD), "--nodes", "40", "--csv", str(out),
                 "--json", str(doc)]) == status
    err = capsys.readouterr().err
    assert re.fullmatch(rf"morphoshell: {word} after 6 points; the 6 points followed to "
                        rf"lambda = \S+ are kept in {re.escape(str(doc))} and "
                        rf"{re.escape(str(out))}, marked partial\n", err), err
    assert re.match(rf"# morphoshell continue PARTIAL: the branch stopped early: {word}\n",
                    out.read_text())
    data = json.loads(doc.read_text())
    assert data["complete"] is False and len(data["points"]["lambda"]) == 6
    assert data["seconds"] > 0      # (it said 0.0 after ~3 s of work: audit 17)


def test_an_interrupt_in_the_half_mesh_check_keeps_the_complete_walk(tmp_path, capsys,
                                                                     monkeypatch):
    """Ctrl-C after the walk, in the half-mesh check of its events: the bare "interrupted",
    nothing written (audit 17).  The walked branch is written, marked partial with what was
    not done (its events' errors), and its time is the real one."""
    from morphoshell.solvers import branches

    def cut(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(branches, "event_errors", cut)
    out, doc = tmp_path / "c.csv", tmp_path / "c.json"
    assert main(["continue", str(FOLD), "--nodes", "40", "--csv", str(out),
                 "--json", str(doc)]) == 130
    err = capsys.readouterr().err
    what = ("interrupted during the half-mesh check of the branch's events (its points "
            "complete, their lambda_error not estimated)")
    assert re.fullmatch(rf"morphoshell: {re.escape(what)} after (\d+) points; the \1 points "
                        rf"followed to lambda = 1 are kept in {re.escape(str(doc))} and "
                        rf"{re.escape(str(out))}, marked partial\n", err), err
    assert out.read_text().startswith(f"# morphoshell continue PARTIAL: the branch stopped "
                                      f"early: {what}\n")
    data = json.loads(doc.read_text())
    assert data["complete"] is False and data["points"]["lambda"][-1] == 1.0
    assert data["ended"]["status"] == "Interrupted" and data["seconds"] > 0


def test_a_switch_run_interrupted_in_the_main_branchs_check_keeps_its_layout(tmp_path, capsys,
                                                                             monkeypatch):
    """`--switch` cut in the main branch's half-mesh check: the CSV had no ``branch`` column
    and the JSON no ``switched`` nor ``not_done``, and the message did not say the switches
    were not followed, where a cut in the switches does both (audit 22 F3): a reader keyed
    on ``branch`` failed. Now the layout is the switches' whenever the run stops."""
    from morphoshell.solvers import branches

    def cut(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(branches, "event_errors", cut)
    out, doc = tmp_path / "s.csv", tmp_path / "s.json"
    assert main(["continue", str(example_path("blister")), "--nodes", "40", "--switch", "2",
                 "--csv", str(out), "--json", str(doc)]) == 130
    err = capsys.readouterr().err.splitlines()[-1]
    assert err.startswith("morphoshell: interrupted during the half-mesh check") and \
        err.endswith("marked partial; 1+, 1-, 2+, 2- not followed"), err
    comment, head, *rows = out.read_text().splitlines()
    assert comment.startswith("# morphoshell continue PARTIAL: the branch stopped early")
    assert head.startswith("branch,lambda,") and {r.split(",")[0] for r in rows} == {"main"}
    data = json.loads(doc.read_text())
    assert data["switched"] == [] and data["not_done"] == "1+, 1-, 2+, 2- not followed"
    assert data["complete"] is False


def test_a_snaps_line_has_no_error_clause(capsys):
    """Error estimates are a fold's or branch point's; a snap's landing line said "no error
    estimate (the half mesh holds no point before it)", as if a check had failed (audit 22
    F4). Its line has none; the fold it snaps from keeps its estimate."""
    assert main(["continue", str(FOLD), "--nodes", "40", "--follow", "stable"]) == 0
    lines = capsys.readouterr().out.splitlines()
    snaps = [line for line in lines if line.lstrip().startswith("snap ")]
    folds = [line for line in lines if line.lstrip().startswith("fold ")]
    assert snaps and folds
    assert not any("error" in line for line in snaps), snaps
    assert all("error in lambda" in line for line in folds), folds


def test_switch_follows_both_halves_of_the_branch_through_a_branch_point(tmp_path, capsys):
    """`continue --switch 1` on the packaged example blister: the flat branch, then both
    halves of the dome branch through its first branch point, stable at lambda = 1 and
    mirror images; the CSV names each row's branch, the JSON holds them."""
    problem = example_path("blister")
    paths = {k: tmp_path / f"b.{k}" for k in ("csv", "json", "png")}
    assert main(["continue", str(problem), "--nodes", "40", "--switch", "1",
                 "--csv", str(paths["csv"]), "--json", str(paths["json"]),
                 "--plot", str(paths["png"])]) == 0
    stdout = capsys.readouterr().out
    assert stdout.count("switched at branch point 1") == 2
    with paths["csv"].open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["branch", *COLUMNS]
    assert [r["branch"] for r in rows][::len(rows) - 1] == ["main", "1-"]
    ends = {name: [r for r in rows if r["branch"] == name][-1] for name in ("1+", "1-")}
    for end in ends.values():
        assert end["lambda"] == "1.0" and end["stable"] == "true"
    up, down = float(ends["1+"]["z_end"]), float(ends["1-"]["z_end"])
    assert up > 0.25 and abs(up + down) < 1e-12 * up         # mirror images
    doc = json.loads(paths["json"].read_text())
    assert [b["name"] for b in doc["switched"]] == ["1+", "1-"]
    assert doc["switched"][0]["origin"] == float(
        next(r["lambda"] for r in rows if r["event"] == "branch_point"))
    assert paths["png"].stat().st_size > 20_000


def test_switch_beyond_the_branch_points_is_a_note():
    """(The fold shell has no branch point: --switch has nothing to follow; said, not failed.)"""
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["continue", str(FOLD), "--nodes", "40", "--switch", "2"]) == 0
    assert "note: --switch 2: the branch has 0 branch point(s)" in out.getvalue()


def test_a_failed_switch_exits_3_and_keeps_the_branches_followed(tmp_path, capsys,
                                                                  monkeypatch):
    """A switch that fails after the main branch's work (a point not a simple branch point,
    or its steps ending) exited 2, as bad input, and wrote nothing (a user audit): it is
    named, the main branch and the halves that were followed are written, and the exit
    status is a solver failure's, 3."""
    from morphoshell.solvers import branches
    from morphoshell.solvers.results import SolverError

    real = branches.switch_branch

    def half(branch, at, direction=1.0, **kwargs):
        if direction < 0:
            raise SolverError("the branch ended at 0.5 of the way (test)", "Branch_Ended")
        return real(branch, at, direction, **kwargs)

    monkeypatch.setattr(branches, "switch_branch", half)
    out = tmp_path / "b.csv"
    assert main(["continue", str(example_path("blister")), "--nodes", "40", "--switch", "1",
                 "--csv", str(out)]) == 3
    captured = capsys.readouterr()
    assert "switch at branch point 1- failed: the branch ended" in captured.out
    assert "1 switch(es) of branches failed: 1-" in captured.err
    with out.open() as fh:
        names = {r["branch"] for r in csv.DictReader(fh)}
    assert names == {"main", "1+"}


def test_an_interrupt_in_the_switches_keeps_the_branches_followed(tmp_path, capsys,
                                                                   monkeypatch):
    """Ctrl-C in the third branch's half-mesh check (the switch at 1-, its walk complete):
    the main branch and 1+, complete, had been lost with it (audit 17).  All three are
    written, 1- marked as stopped, the file marked partial with what was not done; exit
    status 130."""
    from morphoshell.solvers import branches

    real, calls = branches.event_errors, []

    def third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(branches, "event_errors", third)
    out, doc = tmp_path / "b.csv", tmp_path / "b.json"
    assert main(["continue", str(example_path("blister")), "--nodes", "40", "--switch", "1",
                 "--csv", str(out), "--json", str(doc)]) == 130
    err = capsys.readouterr().err.splitlines(keepends=True)[-1]     # (after the warnings)
    assert re.fullmatch(r"morphoshell: interrupted during the switch at branch point 1-: its "
                        r"\d+ points followed kept; the main branch and the switched branches "
                        rf"followed are kept in {re.escape(str(doc))} and "
                        rf"{re.escape(str(out))}, marked partial\n", err), err
    head, *rows = out.read_text().splitlines()
    assert head.startswith("# morphoshell continue PARTIAL: not all done: interrupted "
                           "during the switch at branch point 1-")
    assert {row.split(",")[0] for row in rows[1:]} == {"main", "1+", "1-"}
    data = json.loads(doc.read_text())
    assert data["complete"] is False and "1-" in data["not_done"]
    assert [b.get("complete", True) for b in data["switched"]] == [True, False]


def test_an_interrupt_while_drawing_the_plot_writes_the_data(tmp_path, capsys, monkeypatch):
    """Ctrl-C while the plot is drawn (about a second): nothing had been written (audit 17).
    The JSON and CSV are, whole (not marked); the message says the plot was not."""
    import morphoshell.plotting

    def cut(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(morphoshell.plotting, "plot_branch", cut)
    paths = {k: tmp_path / f"p.{k}" for k in ("csv", "json", "png")}
    assert main(["continue", str(FOLD), "--nodes", "40", "--csv", str(paths["csv"]),
                 "--json", str(paths["json"]), "--plot", str(paths["png"])]) == 130
    err = capsys.readouterr().err.splitlines(keepends=True)[-1]     # (after the warnings)
    assert err == (f"morphoshell: interrupted while writing: the plot {paths['png']} not "
                   f"drawn; the main branch is kept in {paths['json']} and {paths['csv']}\n")
    assert not paths["png"].exists() and paths["csv"].read_text().startswith("lambda,")
    assert "complete" not in json.loads(paths["json"].read_text())


def test_plot_is_a_journal_figure_with_truetype_fonts_and_one_column_without_shapes(tmp_path):
    """`continue --plot` writes the journal-style figure: in a PDF the fonts are TrueType (no
    Type 3, which journals refuse); two columns (7 in) with the shapes, one (3.4 in) with
    --no-plot-shapes: the PNG's width in pixels at the 300 dpi of `save`."""
    import struct

    problem = example_path("blister")
    pdf, wide, narrow = tmp_path / "b.pdf", tmp_path / "wide.png", tmp_path / "narrow.png"
    assert main(["continue", str(problem), "--nodes", "40", "--plot", str(pdf)]) == 0
    # (matplotlib embeds its TrueType fonts as CID-keyed TrueType: CIDFontType2)
    assert b"/Type3" not in pdf.read_bytes() and b"/CIDFontType2" in pdf.read_bytes()
    for path, extra in ((wide, []), (narrow, ["--no-plot-shapes"])):
        assert main(["continue", str(problem), "--nodes", "40", "--plot", str(path),
                     *extra]) == 0
    width = {p: struct.unpack(">I", p.read_bytes()[16:20])[0] for p in (wide, narrow)}
    assert width == {wide: 7.0 * 300, narrow: 3.4 * 300}


def test_a_branch_that_crosses_the_axis_ends_there_written_with_status_3(tmp_path, capsys):
    """A uniform cap (toy 1, h = 0.2, cut = 1) continued in k to 9.9 on 100 nodes (audit 14
    F3): past k ≈ 8.55 its meridian crosses the axis; the branch ends at its last physical
    point, the outputs are written (the JSON's `ended`), the summary says why, exit 3."""
    csv_path, json_path = tmp_path / "cap.csv", tmp_path / "cap.json"
    status = main(["continue", str(example_path("toy1_sphere")), "--set", "h=0.2", "--set",
                   "cut=1.0", "--set", "k=1.0", "--param", "k", "--to", "9.9", "--nodes",
                   "100", "--csv", str(csv_path), "--json", str(json_path)])
    out, err = capsys.readouterr()
    assert status == 3 and "Meridian_Crosses_Axis" in err
    ended = json.loads(json_path.read_text())["ended"]
    assert ended["status"] == "Meridian_Crosses_Axis" and 0.8 < ended["lambda"] < 0.9
    with csv_path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[-1]["lambda"]) == ended["lambda"]
    assert "(Meridian_Crosses_Axis: the last physical state): stable" in out
    folds = [r for r in rows if r["event"] == "fold"]
    assert len(folds) == 4 and all(0 < float(r["lambda_error"]) < 1e-4 for r in folds)


def test_folds_the_mesh_does_not_resolve_are_flagged(tmp_path, capsys, caplog):
    """The anisotropic toy shell in f0 to 4.5 on 100 nodes (audit 14 F2): its two folds are
    not on the half mesh; the summary and the CSV (`inf`) say so, a warning advises a finer
    mesh; the exit status stays 0 (the branch itself was followed)."""
    csv_path = tmp_path / "t3.csv"
    status = main(["continue", str(example_path("toy3_anisotropic")), "--param", "f0", "--to",
                   "4.5", "--nodes", "100", "--csv", str(csv_path)])
    out = capsys.readouterr().out
    assert status == 0
    assert out.count("not resolved (not on the half mesh)") == 2
    assert "does not resolve" in caplog.text and "--nodes 199" in caplog.text
    # nor its end, printed to 10 digits and 0.78 R off in z_end: solve()'s warning and
    # estimate (audit 22 F5)
    assert "at the branch's end, lambda = 1 (f0 = 4.5), the error estimate of z_end is 0.42" \
        in caplog.text
    # (the end named by the continued parameter's value too, as the events are: audit 24 F5)
    assert re.search(r"end at lambda = 1, f0 = 4.5: stable, .*; error estimate 0.027 of the "
                     r"energy, 0.42 R or rad at the edges \(vs 50 nodes, order 4\)", out)
    with csv_path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[-1]["z_end_error"]) == pytest.approx(0.42, abs=0.005)
    assert [r["lambda_error"] for r in rows if r["event"] == "fold"] == ["inf", "inf"]
    assert all(r["lambda_error"] == "" for r in rows if not r["event"])


#: A `continue` that waits after its 6th point (for the SIGTERM of the test that starts it).
_WAITING = """
import sys, time
from morphoshell.cli import main
from morphoshell.solvers import branches
real, calls = branches._Walk.record, []
def record(walk, *args, **kwargs):
    real(walk, *args, **kwargs)
    calls.append(1)
    if len(calls) == 6:
        print("ready", flush=True)
        time.sleep(60)
branches._Walk.record = record
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_to_a_background_job_writes_its_points_marked_partial(tmp_path):
    """A `continue` started in a script's background (`cmd &`: Ctrl-C ignored) and sent
    SIGTERM died at once, exit 143, no message and no file (audit 22, F1): the SIGTERM
    handler was installed only where Ctrl-C had Python's own.  A real process, started with
    Ctrl-C ignored as such a shell starts it."""
    import os
    import signal
    import subprocess
    import sys

    out, doc = tmp_path / "b.csv", tmp_path / "b.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    child = subprocess.Popen(
        [sys.executable, "-c", _WAITING, "continue", str(FOLD), "--nodes", "40", "--csv",
         str(out), "--json", str(doc)], env=env, text=True, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        assert child.stdout.readline() == "ready\n"
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 143, err
    assert re.fullmatch(r"morphoshell: terminated \(SIGTERM\) after 6 points; the 6 points "
                        rf"followed to lambda = \S+ are kept in {re.escape(str(doc))} and "
                        rf"{re.escape(str(out))}, marked partial\n", err), err
    assert json.loads(doc.read_text())["complete"] is False
