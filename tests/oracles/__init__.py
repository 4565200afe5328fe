"""Test oracles: independent NumPy re-derivations the compiled models are checked against.

Not part of the package (nothing in ``grasping_sym`` imports them). ``reference`` evaluates a
planar scene's closed loop by SymPy ``lambdify`` (also the benchmarks' hand-written baseline),
``reference3d`` the one-finger 3D scene regular at rest, ``reference3d_paper`` the paper's
moving-frame formulation of it.
"""
