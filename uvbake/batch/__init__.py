"""``uvbake batch``: thousands of assets on Dask, resumable, one bad mesh never stops the rest.

    table = uvbake.batch.run(["scans/"], "out", alpha=0.5)            # a LocalCluster on this machine
    table = uvbake.batch.run(["list.csv"], "out", client=Client("tcp://sched:8786"))

One Dask task per asset; each asset runs in a child process with its own time limit
(:mod:`uvbake.batch.task`), outputs are keyed by the input's bytes and the options and committed with a
marker written last (:mod:`uvbake.batch.inputs`, :mod:`uvbake.batch.task`), and the summary
(``summary.parquet``, ``summary.csv``) and a static ``report.html`` are written at the end
(:mod:`uvbake.batch.report`).
"""

from uvbake.batch.run import COLUMNS, exit_status, normalise_options, run

__all__ = ["COLUMNS", "exit_status", "normalise_options", "run"]
