"""The physics, without numerics: undeformed geometry, intrinsic profiles, energy.

A :class:`~morphoshell.model.problem.Problem` names a shell (geometry, profile
family and its parameters, thickness, ends, theory); :mod:`.energy` turns it
into strains and the energy density of the paper's Materials and Methods,
Eqs. (5)-(7), as CasADi expressions.  Everything above derives from these.
"""
