"""Benchmarks of grasping_sym (kept apart from the tests): ``python -m benchmarks.run``.

Modules, one concern each:

- ``machine``: CPU, cores, load and package versions recorded with every run;
- ``timing``: medians, best-of-repeats, timing in fresh interpreter processes;
- ``scenes``: the extra scenes (an ellipse object for the cold-build test; 1-3 fingers);
- ``build_stages``: derivation / translation / C / compile / cached-load times and op counts;
- ``rhs_cost``: cost of one right-hand-side evaluation along every call path;
- ``work_precision``: wall time against final-state error for every integrator (and, with
  projection, on the scene without Baumgarte stabilisation) and the lambdify +
  ``scipy.integrate.solve_ivp`` baseline (on the paper's equations and without Baumgarte),
  with constraint residual and energy drift; the (rtol, atol) grid near error 1e-8 searched
  alike for ours and the peers; the comparison at equal error (also with both sides on one
  formulation) and the method choice per accuracy band;
- ``peer_curves``: the peers of ``peers/`` (CasADi uncompiled, PyDy Cython) as work-precision
  rows, their residual and drift measured by our compiled outputs;
- ``paper3d``: the same for the 3D scene;
- ``report``: Markdown tables, JSON and the work-precision plot in ``benchmarks/results/``;
- ``build_scaling`` (``python -m benchmarks.build_scaling``): build and call costs over shapes,
  splines through 10 to 1000 points included;
- ``build_fingers`` (``python -m benchmarks.build_fingers``): the same over 1, 2, 3 fingers in 2D;
- ``paper3d_singularity``: the figure of the paper's moving frames as paper3d comes to rest.
"""
