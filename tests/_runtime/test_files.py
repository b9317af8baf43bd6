"""Files written all or nothing: a failure names the file asked for."""
import pytest

from morphoshell._runtime.files import replace_named


def test_a_rename_that_fails_names_the_target_not_the_temporary_file(tmp_path):
    """The message named `.t01_free.t3l5exwr.tmp`, a file the user never sees (user audit 5)."""
    tmp = tmp_path / ".t01_free.abc.tmp"
    tmp.write_text("{}")
    target = tmp_path / "t01_free.json"
    (target / "inside").mkdir(parents=True)     # (a folder in its place: no rename onto it)
    with pytest.raises(OSError) as caught:
        replace_named(tmp, target)
    assert caught.value.filename == str(target) and ".tmp" not in str(caught.value)
    assert "cannot write it" in caught.value.strerror


def test_a_campaign_record_that_cannot_be_replaced_is_named(tmp_path, capsys):
    """The same through a campaign, whose record's place is taken by a folder."""
    from pathlib import Path

    from morphoshell.cli import main

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "out"
    (out / "t01_flat.json" / "inside").mkdir(parents=True)
    assert main(["campaign", str(root / "data" / "synthetic_inversion"), "--variants", "flat",
                 "--timepoints", "t01", "--nodes", "60", "--workers", "1",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"({out / 't01_flat.json'})" in err and ".tmp" not in err
