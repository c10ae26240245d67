"""Numerical machinery with no physics: linear solvers and their reuse, Krylov, orderings, time schemes, assembly."""
