"""Sweeps and batch runs (docs/sweeps.md): the sweep file's runs on local processes or a Ray cluster.

``sweep.py`` runs a sweep file and writes its results (``run_sweep``), ``worker.py`` is one run in a worker,
``metrics.py`` the metric registry, ``plots.py`` the plots, and ``runner.py`` the runner itself (plain-data
tasks in worker processes, local or Ray), which the benchmark uses too.
"""
