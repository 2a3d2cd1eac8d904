"""The benchmarks of ``irlsim bench`` (docs/design/performance.md): measured, never asserted.

- :mod:`irlsim.bench.report`: :func:`~irlsim.bench.report.run_benchmarks` with
  :class:`~irlsim.bench.report.BenchRun`, the sections, bench.md;
- :mod:`irlsim.bench.planner`: the planner cycle;
- :mod:`irlsim.bench.episodes`: collection, inference, the Gymnasium env;
- :mod:`irlsim.bench.scale`: the local pool against Ray, devices and precisions;
- :mod:`irlsim.bench.synthetic`: a tiny in-memory dataset with a known reward (what ``--scale`` and
  ``--growth`` train on);
- :mod:`irlsim.bench.growth_report`: ``--growth``, :func:`~irlsim.bench.growth_report.run_growth` with
  :class:`~irlsim.bench.growth_report.GrowthRun`: how each cost grows with its size (the curves of
  :mod:`irlsim.bench.growth` and :mod:`irlsim.bench.growth_train`), fitted, as JSON, Markdown and PNG.

Nothing is imported here: ``irlsim bench`` sets one thread before numpy is loaded.
"""
