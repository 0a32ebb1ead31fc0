"""The comparative study: what ``glvox compare`` and ``glvox bench`` run.

* :mod:`.plan`: contenders (glvox methods, peers, the calibration workload)
  x meshes x sizes; :mod:`.harness`: the one runner (cold run, interleaved
  timed rounds, agreement with the exact references), and :func:`.harness.timed`
  for scripts;
* :mod:`.compare`, :mod:`.report`, :mod:`.render`: ``glvox compare``
  (separability, resumable results, tables, plots, pictures);
* :mod:`.bench`, :mod:`.bench_report`, :mod:`.peers`, :mod:`.calibration`,
  :mod:`.regression`, :mod:`.coldstart`, :mod:`.ab`: ``glvox bench`` (ratios
  to the peer voxelizers, the regression checks, cold starts);
* :mod:`.options`: both commands' presets and arguments (light: the CLI
  imports it at start-up); :mod:`.meshes`: where the shared meshes are;
  :mod:`.zhang`: Zhang et al.'s Table 1 triangle and operation count.

The scripts in the checkout's ``compare/`` folder reproduce single tables of
the papers with these helpers; nothing here imports them.
"""
