"""Evaluate CasADi Functions straight into NumPy arrays.

Converting between ``casadi.DM`` and NumPy costs a fixed time per element, which
would dominate a warm re-solve (the NLP parameter vector alone has ~19 entries per
cell).  ``Function.buffer()`` reads and writes preallocated memory instead.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["Buffered"]


class Buffered:
    """A CasADi Function bound to preallocated NumPy inputs and outputs.

    Call it with one array per input (flattened column-major, as CasADi
    stores dense matrices); it returns copies of the outputs as flat arrays.
    Every input must be given: a missing input would read zeros.
    """

    def __init__(self, f: ca.Function):
        self.function = f
        self._buf, self._eval = f.buffer()
        self.args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self.args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self.res):
            self._buf.set_res(i, memoryview(r))

    def __call__(self, *args) -> list[np.ndarray]:
        if len(args) != len(self.args):
            raise TypeError(f"{self.function.name()} takes {len(self.args)} inputs, "
                            f"got {len(args)}")
        for dst, v in zip(self.args, args):
            dst[:] = np.ravel(v, order="F")
        self.run()
        return [r.copy() for r in self.res]

    def run(self) -> None:
        """Evaluate on the inputs already in :attr:`args`; the outputs are left in :attr:`res`
        (overwritten by the next evaluation)."""
        self._eval()

    def stats(self) -> dict:
        return self._buf.stats()
