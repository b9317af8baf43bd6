"""Compiled evaluation (morphoshell._runtime.compiled): block maps give the map's numbers."""
import casadi as ca
import numpy as np
import pytest

from morphoshell._runtime.compiled import (BLOCK, BLOCKED_POINTS, CHUNK, PointEvaluator, block_map,
                                   compiled_point_map, point_map_function)


def _point():
    s, p = ca.SX.sym("s"), ca.SX.sym("p", 2)
    return ca.Function("point", [s, p], [ca.vertcat(ca.sin(p[0] * s), s * p[1]), ca.exp(-s)])


@pytest.mark.parametrize("n", [1, BLOCK, BLOCKED_POINTS, BLOCKED_POINTS + 5, 3 * BLOCKED_POINTS - 1])
def test_block_map_is_the_map(n):
    """Padded blocks (or the map itself, below BLOCKED_POINTS), mapped and shared inputs:
    the same numbers as f.map(n), to the bit."""
    f = _point()
    s = np.linspace(0.1, 2.0, n).reshape(1, -1)
    shared, mapped = np.array([1.3, -0.7]), np.vstack([np.linspace(1, 2, n), np.cos(s.ravel())])
    for p in (shared, mapped):
        want = [np.array(v) for v in f.map(n)(s, p)]
        got = [np.array(v) for v in
               ca.Function("g", [], list(compiled_point_map(f, n, ca.DM(s), ca.DM(p))))()
               .values()]
        assert [g.shape for g in got] == [w.shape for w in want] == [(2, n), (1, n)]
        assert all(np.array_equal(g, w) for g, w in zip(got, want))
    by_function = point_map_function(f, n)(s, mapped)
    assert np.array_equal(np.array(by_function[0]), np.array(f.map(n)(s, mapped)[0]))
    once = point_map_function(f, n, shared=(1,))(s, shared)
    assert np.array_equal(np.array(once[0]), np.array(f.map(n)(s, shared)[0]))


def test_block_map_names_an_input_of_the_wrong_size():
    f = _point()
    with pytest.raises(ValueError, match="input 1 of point has 3 columns; expected 1 or 10"):
        block_map(f, f, 10, [ca.MX.sym("s", 1, 10), ca.MX.sym("p", 2, 3)])


@pytest.mark.parametrize("n", [0, 1, CHUNK - 1, CHUNK, CHUNK + 1, 3 * CHUNK + 17])
def test_point_evaluator_is_the_map_at_any_number_of_points(n):
    """One evaluator of CHUNK points, called in chunks (the last padded): f.map(n)'s numbers
    to the bit, each output (rows × n)."""
    f = _point()
    evaluate = PointEvaluator(f)
    s = np.linspace(0.1, 2.0, n)
    p = np.array([1.3, -0.7])
    got = evaluate(s, p)
    assert [g.shape for g in got] == [(2, n), (1, n)]
    if n:
        want = [np.array(v) for v in f.map(n)(s.reshape(1, -1), p)]
        assert all(np.array_equal(g, w) for g, w in zip(got, want))


def test_a_compile_is_noted_once_by_default_and_a_cached_library_not(tmp_path, monkeypatch):
    """The first run on a machine compiled kernels for up to 11 s without a word (audit 18
    F6): the first compile of a process says so at NOTE, which the command line shows
    unless --quiet (``morphoshell: note: ...``, naming the cache); a second compile in the
    same process, and a library found in the cache, say nothing."""
    import io
    import shutil

    from morphoshell._runtime import compiled
    from morphoshell._runtime.console import configure

    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("MORPHOSHELL_CACHE_DIR", str(tmp_path / "cache"))
    x = ca.SX.sym("x")
    first, second = (ca.Function(name, [x], [x * x + c]) for name, c in (("f1", 1), ("f2", 2)))

    def said(verbosity: int, *functions) -> str:
        stream = io.StringIO()
        restore = configure(verbosity, stream)
        try:
            for f in functions:
                compiled.compiled_library(f.name(), [f], compiler)
        finally:
            restore()
        return stream.getvalue()

    compiled._note_compiling.cache_clear()      # (as in a new process)
    text = said(0, first, second)
    assert text == (f"morphoshell: note: compiling C kernels for this machine, once (a few "
                    f"seconds; about 10 s more for a KKT fit); cached in {tmp_path / 'cache'}\n")
    compiled._note_compiling.cache_clear()
    assert said(0, first, second) == ""          # both cached
    assert said(-1, ca.Function("f3", [x], [x + 3])) == ""    # --quiet
