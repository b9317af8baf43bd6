"""The gradient fit (fitting.nested) stops at its best point, and only at a stationary one
says it converged."""
import numpy as np
import pytest


def test_a_stalled_gradient_fit_keeps_the_state_of_its_best_point():
    """When every trial fails (a fold of the branch) the gradient fit stops at its best point,
    and that point's state is made current again: it may have left the archive of recent
    states, and the re-solve from another one failed the whole fit (unstressed on the
    synthetic t06 from the family's defaults)."""
    import types

    import morphoshell.fitting.nested as fitting
    from morphoshell.solvers.results import SolverError

    target = np.array([1.0, 2.0])

    class Inner:
        n, trials, kept, costs = 2, 0, None, {}

        def solve(self, theta, trial=False):
            if trial:
                self.trials += 1
                if self.trials > 3:
                    raise SolverError("no convergence", "Restoration_Failed")
            return ("state", tuple(np.asarray(theta, dtype=float)))

        def residuals(self, eq):       # cubic: Gauss-Newton needs many steps
            r = np.concatenate([(np.asarray(eq[1]) - target) ** 3, [0.0, 0.0]])
            self.costs[eq[1]] = float(r @ r)
            return r

        def jacobian(self, eq, theta):
            return np.vstack([np.diag(3 * (np.asarray(theta) - target) ** 2), np.zeros((2, 2))])

        def keep(self, theta, eq):
            self.kept = (tuple(theta), eq)

    inner = Inner()
    spec = types.SimpleNamespace(theta0=np.array([0.0, 0.0]),
                                 box=lambda: (np.full(2, -np.inf), np.full(2, np.inf)))
    theta, evaluations, converged, message, stop = fitting.gradient_fit(spec, inner, 1e-15, 200)
    best = min(inner.costs, key=inner.costs.get)
    assert not converged and "best point reached" in message and stop == "Fit_Stalled"
    assert evaluations == 3 + fitting.MAX_FAILED_TRIALS
    assert tuple(theta) == best and inner.kept == (best, ("state", best))


def test_a_gradient_fit_that_stalls_short_of_a_stationary_point_is_not_converged():
    """Trial points beyond theta_0 = 0.5 jump to another branch, misfit by 10 everywhere:
    least_squares shrinks its trust region there until xtol stops it, at a point where the
    gradient is far from zero.  That is a stall, not convergence (the synthetic campaign's
    unstressed t09 "converged" by xtol at E_fit 0.32 R, and went on to 0.038 R).
    The same problem without the jump converges, with the gradient at round-off."""
    import types

    import morphoshell.fitting.nested as fitting

    target = np.array([1.0, 2.0])

    class Inner:
        n = 2

        def __init__(self, jump):
            self.jump = jump

        def solve(self, theta, trial=False):
            theta = np.asarray(theta, dtype=float)
            return (theta, self.jump and theta[0] > 0.5)

        def residuals(self, eq):
            theta, other = eq
            r = np.concatenate([theta - target, [0.0, 0.0]])
            return r + 10.0 if other else r

        def jacobian(self, eq, theta):      # the smooth branch's: it cannot see the jump
            return np.vstack([np.eye(2), np.zeros((2, 2))])

        def keep(self, theta, eq):
            pass

    spec = types.SimpleNamespace(theta0=np.array([0.0, 0.0]),
                                 box=lambda: (np.full(2, -np.inf), np.full(2, np.inf)))
    theta, _, converged, message, stop = fitting.gradient_fit(spec, Inner(True), 1e-10, 200)
    assert theta[0] == pytest.approx(0.5, abs=1e-3) and not converged
    assert "not a stationary point" in message and stop == "Fit_Not_Stationary"
    theta, _, converged, message, stop = fitting.gradient_fit(spec, Inner(False), 1e-10, 200)
    assert converged and theta == pytest.approx(target, abs=1e-8) and stop == "Fit_Converged"
    # out of evaluations (max_nfev) it says so
    _, evaluations, converged, _, stop = fitting.gradient_fit(spec, Inner(False), 1e-10, 1)
    assert evaluations == 1 and not converged and stop == "Maximum_Evaluations_Exceeded"


def test_nelder_mead_counts_its_evaluations_on_a_progress_bar(monkeypatch):
    """Thousands of evaluations (the default limit is 20 000; minutes at 200 nodes) were
    silent on a terminal: a bar (console.counter, shown on a terminal only) counts every
    evaluation against the limit, the start's included."""
    import contextlib
    import types

    import morphoshell.fitting.nested as fitting

    bars = []

    @contextlib.contextmanager
    def counter(total=None, *, desc="", unit="it", enabled=None):
        bars.append(types.SimpleNamespace(total=total, desc=desc, unit=unit, n=0))
        bars[-1].update = lambda n=1: setattr(bars[-1], "n", bars[-1].n + n)
        yield bars[-1]

    target = np.array([1.0, 2.0])

    class Inner:
        n = 2

        def solve(self, theta, trial=False):
            return np.asarray(theta, dtype=float)

        def residuals(self, eq):
            return np.concatenate([eq - target, [0.0, 0.0]])

    monkeypatch.setattr(fitting, "counter", counter)
    spec = types.SimpleNamespace(theta0=np.array([0.0, 0.0]), problem=lambda theta: None,
                                 box=lambda: (np.full(2, -np.inf), np.full(2, np.inf)))
    theta, evaluations, converged, _, _ = fitting.nelder_mead_fit(spec, Inner(), 1e-12, 300)
    assert converged and theta == pytest.approx(target, abs=1e-4)
    [bar] = bars
    assert (bar.total, bar.desc, bar.unit) == (300, "Nelder-Mead", "evaluation")
    assert bar.n == evaluations + 1 and evaluations > 50


def test_a_gradient_fit_whose_mesh_moves_starts_again_from_its_end_on_the_new_one():
    """A solve that moves the inner problem to a new mesh changes E_fit under
    least_squares: here every point costs 100 more on the new mesh, so that each trial
    after the move lies above the best cost of the old one and is rejected, and the fit
    used to stop by xtol where the mesh moved, "converged" (the synthetic t02 embryo's
    free fit at 60 nodes: E_fit 0.0124 R for 0.0122 R).  The fit starts again from that
    end, on the new mesh, and goes on to that mesh's minimum."""
    import types

    import morphoshell.fitting.nested as fitting

    target = np.array([1.0, 2.0])

    class Inner:
        n = 2

        def __init__(self):
            self.solver = types.SimpleNamespace(mesh="old")

        def solve(self, theta, trial=False):
            theta = np.asarray(theta, dtype=float)
            if theta[0] > 0.5 and self.solver.mesh == "old":   # (too far for the old mesh)
                self.solver = types.SimpleNamespace(mesh="new")
            return theta, self.solver.mesh

        def residuals(self, eq):
            theta, mesh = eq
            return np.concatenate([theta - target, [0.0, 10.0 if mesh == "new" else 0.0]])

        def jacobian(self, eq, theta):
            return np.vstack([np.eye(2), np.zeros((2, 2))])

        def keep(self, theta, eq):
            pass

    spec = types.SimpleNamespace(theta0=np.array([0.0, 0.0]),
                                 box=lambda: (np.full(2, -np.inf), np.full(2, np.inf)))
    inner = Inner()
    theta, evaluations, converged, message, stop = fitting.gradient_fit(spec, inner, 1e-10, 200)
    assert inner.solver.mesh == "new"
    assert converged and stop == "Fit_Converged", message
    assert theta == pytest.approx(target, abs=1e-8)



def test_a_trial_that_moved_the_mesh_onto_another_branch_leaves_no_trace(monkeypatch):
    """A trial whose solve moves the inner problem to a mesh of its own can land on another
    branch of equilibria there; the inner problem then holds only that state, and every
    later solve followed it (the synthetic campaign's unstressed t08: a trial jumped from
    E_fit 0.042 to 0.67 R, the fit ended at 0.755 R, and the next four timepoints' fits
    failed).  Such a trial, far above the best point (REMESH_JUMP), makes the best
    point's state and mesh current again, and the fit goes on on its branch.  (Fails
    without it: the fit ends on the other branch, its residual 10 off.)"""
    import types

    import morphoshell.fitting.nested as fitting

    target = np.array([1.0, 2.0])

    class Inner:
        n = 2

        def __init__(self):
            self.mesh, self.branch, self.jumped = "old", "fit's", False

        def solve(self, theta, trial=False):
            theta = np.asarray(theta, dtype=float)
            if trial and theta[0] > 0.5 and not self.jumped:  # (stale mesh: a mesh of its own)
                self.mesh, self.branch, self.jumped = "new", "other", True
            return theta, self.mesh, self.branch

        def residuals(self, eq):
            theta, _, branch = eq
            return np.concatenate([theta - target, [0.0, 10.0 if branch == "other" else 0.0]])

        def jacobian(self, eq, theta):
            return np.vstack([np.eye(2), np.zeros((2, 2))])

        def keep(self, theta, eq):
            self.mesh, self.branch = eq[1], eq[2]

    monkeypatch.setattr(fitting, "_mesh_of", lambda inner: inner.mesh)
    spec = types.SimpleNamespace(theta0=np.array([0.0, 0.0]),
                                 box=lambda: (np.full(2, -np.inf), np.full(2, np.inf)))
    inner = Inner()
    theta, _, converged, message, stop = fitting.gradient_fit(spec, inner, 1e-10, 200)
    assert inner.jumped                      # (the case happened)
    assert converged and stop == "Fit_Converged", message
    assert theta == pytest.approx(target, abs=1e-8)
    assert np.abs(inner.residuals(inner.solve(theta))).max() < 1e-8
