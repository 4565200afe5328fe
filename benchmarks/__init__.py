"""Benchmarks of grasping_sym (kept apart from the tests): ``python -m benchmarks.run``.

Modules, one concern each:

- ``machine``: CPU, cores, load and package versions recorded with every run;
- ``timing``: medians, best-of-repeats, timing in fresh interpreter processes;
- ``scenes``: the extra scene used for the cold-build test (an ellipse object);
- ``build_stages``: derivation / translation / C / compile / cached-load times and op counts;
- ``rhs_cost``: cost of one right-hand-side evaluation along every call path;
- ``work_precision``: wall time against final-state error for every integrator (and, with
  projection, on the scene without Baumgarte stabilisation) and the lambdify +
  ``scipy.integrate.solve_ivp`` baseline, with constraint residual and energy drift; the
  comparison at equal error and the method choice per accuracy band;
- ``peer_curves``: the peers of ``peers/`` (CasADi uncompiled, PyDy Cython) as work-precision
  rows, their residual and drift measured by our compiled outputs;
- ``paper3d``: the same for the 3D scene;
- ``report``: Markdown tables, JSON and the work-precision plot in ``benchmarks/results/``.
"""
