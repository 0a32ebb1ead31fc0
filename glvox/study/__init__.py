"""The comparative study, shipped as ``glvox.compare`` and run as ``glvox compare``.

* :mod:`.harness`: cells (method x mesh x size), timed runs, agreement with
  the references, resumable results;
* :mod:`.report`: markdown tables laid out like the papers' and PNG plots;
* :mod:`.render`: headless pictures (lit voxel cubes, disagreement slices);
* :mod:`.run`: presets and the command line.

The ``table*.py``, ``zhang_table1.py`` and ``bench_*.py`` scripts beside
these reproduce single tables of the papers; run them from a checkout.
"""
