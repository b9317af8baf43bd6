"""Routes to an equilibrium and what comes out of them.

Direct minimisation (:mod:`.direct`), the boundary-value reference (:mod:`.bvp`)
and multiple shooting (:mod:`.shooting`), all from the same symbolic energy;
continuation along a branch, mesh refinement to a tolerance, observables and
parametric derivatives; :func:`~morphoshell.solvers.routes.solve` is the
one-call front door, :mod:`.results` what every route returns.
"""
