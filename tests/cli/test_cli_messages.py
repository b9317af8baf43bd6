"""Refusals that name the file and the value (issue 40): a binary timepoints.csv, a midline of
two points, a negative number in exponent form on the command line."""
from pathlib import Path

from morphoshell.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_a_binary_timepoints_table_is_named(tmp_path, capsys):
    (tmp_path / "timepoints.csv").write_bytes(bytes([0xCE, 0x00, 0xFF, 0x10]) * 50)
    assert main(["campaign", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{tmp_path / 'timepoints.csv'}: not a UTF-8 text" in err
    assert not (tmp_path / "out").exists()


def test_a_two_point_midline_names_its_file(tmp_path, capsys):
    (tmp_path / "t01").mkdir()
    (tmp_path / "t01" / "avg.csv").write_text("r,z\n0,0\n0.5,0.1\n")
    (tmp_path / "timepoints.csv").write_text("timepoint,pseudotime,midline\nt01,0,t01/avg.csv\n")
    assert main(["campaign", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "t01/avg.csv" in err, err


def test_a_negative_number_in_exponent_form_is_a_value(capsys):
    """argparse took -1e9 for an option ("expected 2 arguments"); now it is a value, checked."""
    assert main(["estimate", str(ROOT / "data" / "synthetic_ablations.csv"),
                 "--k-range", "-1e9", "1"]) == 2
    err = capsys.readouterr().err
    assert "-1e9 must be a finite number in [-100, 100]" in err and "expected 2" not in err
    assert main(["solve", "x.toml", "--rtol", "-inf"]) == 2     # (fuzz: "expected one argument")
    err = capsys.readouterr().err
    assert "--rtol: -inf must be a finite number in [1e-10, 1)" in err, err


def test_rtol_refines_within_max_nodes_and_says_how_to_go_further(capsys):
    """An rtol below the solvers' tolerance is refused at once (it had refined silently to
    100 353 nodes, 22 s); --max-nodes bounds the refinement, and the failure names it."""
    toy = str(ROOT / "problems" / "toy2_ablation.toml")
    assert main(["solve", toy, "--rtol", "1e-14"]) == 2
    assert "--rtol: 1e-14 must be a finite number in [1e-10, 1)" in capsys.readouterr().err
    assert main(["solve", toy, "--max-nodes", "400"]) == 2
    assert "give --rtol too" in capsys.readouterr().err
    assert main(["solve", toy, "--nodes", "50", "--rtol", "1e-10", "--max-nodes", "30"]) == 2
    assert "--max-nodes 30 is below the first mesh's 50 nodes" in capsys.readouterr().err
    assert main(["solve", toy, "--nodes", "50", "--rtol", "1e-10", "--max-nodes", "200"]) == 3
    err = capsys.readouterr().err
    assert "Tolerance_Not_Met" in err and "within 200 nodes" in err and "--max-nodes" in err, err


def test_a_k_range_the_shells_cannot_have_is_refused_at_once(capsys):
    """|k| >= 2/h of the thickest shell (h = 0.335, embryo S10): an intrinsic radius below the
    half-thickness; the search of -100..100 ran 84 s before it was refused (issue 40)."""
    import time

    t0 = time.perf_counter()
    assert main(["estimate", str(ROOT / "data" / "synthetic_ablations.csv"),
                 "--k-range", "-100", "100"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("morphoshell: error: --k-range -100 100: "), err
    assert "embryo 'S10'" in err and "2/h = 5.963" in err
    assert time.perf_counter() - t0 < 20


def test_campaign_selections_name_their_option(tmp_path, capsys):
    """The library names its arguments (timepoints, embryo_errors); the command its options."""
    data = str(ROOT / "data" / "synthetic_inversion")
    out = tmp_path / "out"
    assert main(["campaign", data, "--out", str(out), "--timepoints", "t01,t99"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--timepoints 't01,t99': ['t99'] not in" in err, err
    assert main(["campaign", data, "--out", str(out), "--variants", "flat",
                 "--embryo-errors", "free"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--embryo-errors free: ['free'] not among --variants flat" \
        in err, err
    assert not out.exists()


def test_set_names_every_family_and_refuses_a_key_twice(capsys):
    """--set's help lists the parameters of every packaged family from the registry (the
    blister's central_growth had been missing); a key set twice is refused, as a sweep
    refuses it (the last had won silently); an unknown key's message names the solver's."""
    from morphoshell.cli._args import family_keys
    from morphoshell.model.profiles import FAMILIES

    listed = family_keys()
    assert all(f"{name}:" in listed for name in FAMILIES) and "central_growth: G, w" in listed
    assert "volvox: f1..f5, kappa1..kappa4, s1..s4, sigma" in listed
    toy = str(ROOT / "problems" / "toy1_sphere.toml")
    assert main(["solve", toy, "--set", "k=0.5", "--set", "k=1"]) == 2
    assert "--set 'k=1': k is set more than once" in capsys.readouterr().err
    assert main(["solve", toy, "--set", "K=0.5"]) == 2
    assert "and the solver's ['nodes', 'method', 'stages']" in capsys.readouterr().err


def test_a_header_only_midline_has_no_points(tmp_path, capsys):
    """A midline file of its header alone was an internal error (IndexError, exit 1) in fit and
    average (audit 3, #6); now exit 2 naming the file, as an empty file is."""
    (tmp_path / "rz.csv").write_text("r,z\n")
    (tmp_path / "xy.csv").write_text("x,y\n\n")
    trace = str(ROOT / "data" / "synthetic_inversion" / "t02" / "synthetic_embryo1_midline.csv")
    scale = ["--pixel-size", "0.3", "--radius-um", "41.7"]
    for argv, name in ((["fit", str(tmp_path / "rz.csv"), "--variant", "free"], "rz.csv"),
                       (["fit", str(tmp_path / "xy.csv"), "--variant", "free", *scale], "xy.csv"),
                       (["average", trace, str(tmp_path / "rz.csv")], "rz.csv")):
        assert main([*argv, "--json", str(tmp_path / "out.json")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{name}: no points: only the header" in err, err
        assert not (tmp_path / "out.json").exists()


def test_fit_values_it_cannot_take_are_named_with_their_option(tmp_path, capsys):
    """--set sigma=0.3 (in sigma's range) gave SciPy's "Each lower bound must be strictly less
    than each upper bound" (#8), --set f1=5 (bounds 0.5-2) ran to E_fit 16.5 R (#10) and
    --set opening=3.2 blamed the cut (#14, audit 3): now exit 2 before any work, naming the
    option, the value and why."""
    midline = str(ROOT / "data" / "synthetic_inversion" / "t02" / "synthetic_average.csv")
    for value, said in (("sigma=0.3", "--set sigma=0.3: sigma = 0.3 leaves no room for s2"),
                        ("f1=5", "--set f1=5: f1 = 5 lies outside the fit's bounds [0.5, 2]"),
                        ("opening=3.2", "--set opening=3.2: opening (P) = 3.2 is larger than "
                                        "the shell")):
        assert main(["fit", midline, "--variant", "free", "--set", value,
                     "--json", str(tmp_path / "fit.json")]) == 2
        captured = capsys.readouterr()
        assert captured.err.count("\n") == 1 and said in captured.err, captured.err
        assert "E_fit" not in captured.out and not list(tmp_path.iterdir())
    # a start file's value is named by the file, beside the --set that made it unusable
    start = tmp_path / "start.toml"
    start.write_text('[problem]\nfamily = "volvox"\nh = 0.15\nopening = 0.3\n'
                     '[parameters]\nf1 = 5.0\n')
    for extra, said in (([], f"--start {start}: the start f1 = 5.0 lies outside its bounds "
                             f"(0.5, 2)"),
                        (["--set", "f1=1", "--set", "sigma=0.3"],
                         f"--set sigma=0.3, --start {start}: sigma = 0.3 leaves no room")):
        assert main(["fit", midline, "--variant", "free", "--start", str(start), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and said in err, err


def test_campaign_names_the_files_it_wrote(tmp_path):
    """It printed "wrote OUT/<timepoint>_<variant>.json" literally (audit 13, F10): now the
    number of fit files and their names, the first and last of more than three."""
    from types import SimpleNamespace

    from morphoshell.cli.campaign import _written

    def result(names, variants):
        timepoints = [SimpleNamespace(name=n) for n in names]
        return SimpleNamespace(out=tmp_path, timepoints=timepoints, variants=variants,
                               records={(n, v): {} for n in names for v in variants})
    assert _written(result(["t01"], ["flat", "free"])) == (
        f"2 fit files in {tmp_path} (t01_flat.json, t01_free.json)")
    assert _written(result(["t01", "t05"], ["flat", "free", "unstressed"])) == (
        f"6 fit files in {tmp_path} (t01_flat.json, ..., t05_unstressed.json)")


def test_solver_failures_lead_with_their_status_in_the_command_lines_terms(tmp_path, monkeypatch,
                                                                          capsys):
    """Audit 26 F7: `solve --method bvp` failed with "... The maximum number of mesh nodes is
    exceeded. (status 1): ... raise max_nodes ...; the last iterate is attached (.last_iterate)":
    scipy's message and integer for a status, and advice naming an argument and an object the
    command line has not; a thin shell's direct failure had its status 300 characters in."""
    import functools
    import re

    from morphoshell.solvers import bvp

    toy = str(ROOT / "problems" / "toy2_ablation.toml")
    # (solve_bvp's mesh runs out at once, 0.8 s, where the audit's thin shell took 27 s)
    monkeypatch.setattr(bvp, "solve_bvp", functools.partial(bvp.solve_bvp, max_nodes=50))
    for command in ("solve", "ablate"):
        assert main([command, toy, "--method", "bvp", "-q"]) == 3
        err = capsys.readouterr().err
        assert err.startswith("morphoshell: solver failed (status Bvp_Max_Nodes_Exceeded): "), err
        assert "raise max_nodes (Python's solve() only), or use the direct method (--method " \
               "direct)" in err and "attached" not in err and ".last_iterate" not in err, err
    assert main(["solve", toy, "--method", "shooting", "--set", "h=1e-4"]) == 3
    err = capsys.readouterr().err
    assert err.startswith("morphoshell: solver failed (status Shooting_Ill_Conditioned): "), err
    assert "use the direct or bvp route (--method direct or bvp), or raise max_segments " \
           "(Python's solve() only)" in err, err
    thin = tmp_path / "thin.toml"        # (fails in 1 s: audit 26's fuzz)
    thin.write_text('[problem]\nfamily = "central_growth"\ntheory = "classical"\n'
                    'geometry = "disc"\nh = 9.022674264261379e-06\n[parameters]\n'
                    'G = 7.567263866436642\nw = 0.001\n')
    assert main(["solve", str(thin), "--nodes", "40", "-q"]) == 3
    err = capsys.readouterr().err
    assert re.match(r"morphoshell: solver failed \(status \w+\): the shell is thinner", err), err
