"""The shared input checks (_runtime/validate.py): one line naming the value."""
import numpy as np
import pytest

from morphoshell._runtime.validate import instance, name_list, short


def test_short_is_one_line_of_at_most_80_characters():
    """An array's repr spans lines: a message naming it ran over several."""
    text = short(np.zeros((100, 2)))
    assert "\n" not in text and len(text) == 80 and text.endswith("...")
    assert short([1, 2]) == "[1, 2]"


def test_short_names_a_path_whole():
    """A path cut to 80 characters did not name the file (a test's temporary path on CI was
    longer than the one it was written on); a string or path stays whole up to 300."""
    from pathlib import Path

    path = "/tmp/" + "d" * 120 + "/trace.csv"
    assert short(path) == repr(path) and short(Path(path)) == repr(Path(path))
    assert short("x" * 400).endswith("...") and len(short("x" * 400)) == 300


def test_instance_names_the_argument_what_it_must_be_and_what_it_is():
    assert instance("spec", 3, int, "an int") == 3
    with pytest.raises(TypeError, match=r"^spec = 'x' must be a FitSpec, not str$"):
        instance("spec", "x", (int, float), "a FitSpec")


@pytest.mark.parametrize("value, names", [
    ("kelvin", ["kelvin"]), ("kelvin, inner,", ["kelvin", "inner"]), (("a", "b"), ["a", "b"]),
    ("", [])])
def test_name_list_takes_a_sequence_or_one_comma_separated_string(value, names):
    """A single string is one name, not its letters."""
    assert name_list(value) == names
