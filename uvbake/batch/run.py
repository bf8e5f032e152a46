"""``uvbake.batch.run``: many assets on Dask, resumable, one bad mesh never stops the rest."""

from __future__ import annotations

import contextlib
import io as _io
import os
import shutil
import sys
from pathlib import Path
from typing import Any

from uvbake.batch.inputs import collect, file_hash, options_hash
from uvbake.batch.task import (
    MARKER,
    OK_STATUSES,
    STAGING_PREFIX,
    process,
    read_marker,
    write_marker,
)
from uvbake.errors import InputError
from uvbake.flatten.options import DEFAULTS

#: unwrap options a batch accepts, with uvbake.unwrap's defaults (bake: a checker, for the previews)
UNWRAP_DEFAULTS = dict(alpha=DEFAULTS.alpha, init=DEFAULTS.init, backend=DEFAULTS.backend, tol=DEFAULTS.tol,
                       max_iter=DEFAULTS.max_iter, seed=DEFAULTS.seed, texture_size_px=1024, gutter_px=4,
                       bake="checker", auto_cut=True, repair=True, guarantee=True,
                       continuation=DEFAULTS.continuation, max_splits=None, texel_density=None)
#: what else a batch writes per asset
OUTPUT_DEFAULTS = dict(format="obj", preview_size_px=96, atlas_image="auto", atlas_size_px=256)
DEFAULT_TIMEOUT_S = 600.0
#: columns of the summary, in order (the per-stage times are unwrap's, then the batch's own)
COLUMNS = ["asset", "status", "error", "charts", "charts_input", "valid", "n_flipped", "n_overlaps",
           "angle_distortion", "angle_distortion_max", "area_distortion", "packing", "triangles", "vertices",
           "all_converged", "repairs", "t_load_repair_s", "t_charts_s", "t_solve_s", "t_pack_s",
           "t_validate_s", "t_bake_s", "t_total_s", "t_save_s", "t_preview_s", "t_atlas_s", "t_startup_s",
           "t_asset_s", "worker", "input", "key", "mesh", "preview", "atlas", "preview_error"]
#: order of statuses in the report and summary: failures on top
STATUS_ORDER = {"crashed": 0, "timeout": 1, "lost": 2, "failed": 3, "invalid": 4, "done": 5, "cached": 6}


def normalise_options(**options: Any) -> dict[str, Any]:
    """Check the unwrap and output options and return them in canonical form (part of every key).

    Raises InputError naming the option (by its Python name) for anything not usable.
    """
    from uvbake import __version__
    from uvbake.atlas.pack import check_texel_density
    from uvbake.atlas.pipeline import BAKE_MODES, check_texture
    from uvbake.batch.child import ATLAS_IMAGES
    from uvbake.flatten.options import SolveOptions

    unknown = sorted(set(options) - set(UNWRAP_DEFAULTS) - set(OUTPUT_DEFAULTS))
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)}; batch takes "
                         f"{', '.join(sorted(UNWRAP_DEFAULTS) + sorted(OUTPUT_DEFAULTS))}")
    u = {k: options.get(k, v) for k, v in UNWRAP_DEFAULTS.items()}
    if u["texel_density"] is not None and "texture_size_px" not in options:
        u["texture_size_px"] = None               # one density across the batch: each atlas grows to fit
    o = {k: options.get(k, v) for k, v in OUTPUT_DEFAULTS.items()}
    u["alpha"] = SolveOptions(alpha=u["alpha"], init=u["init"], backend=u["backend"], tol=u["tol"],
                              max_iter=u["max_iter"]).alpha
    u["tol"], u["max_iter"], u["seed"] = float(u["tol"]), int(u["max_iter"]), int(u["seed"])
    u["texel_density"] = check_texel_density(u["texel_density"])
    size = check_texture(u["texture_size_px"], u["gutter_px"], u["texel_density"])
    u["gutter_px"] = int(u["gutter_px"])
    u["texture_size_px"] = list(size) if isinstance(size, tuple) else size     # JSON-ready: a side or [W, H]
    if u["bake"] not in BAKE_MODES:
        raise InputError(f"bake={u['bake']!r} is not one of None, 'checker', 'vertex-colors'")
    for k in ("auto_cut", "repair", "guarantee", "continuation"):
        u[k] = bool(u[k])
    if o["format"] not in ("obj", "glb"):
        raise InputError(f"format={o['format']!r} must be 'obj' or 'glb'")
    if o["preview_size_px"] and not 32 <= int(o["preview_size_px"]) <= 2048:
        raise InputError(f"preview_size_px={o['preview_size_px']!r} must be 0 (no preview) or 32 to 2048")
    if o["atlas_image"] and o["atlas_image"] not in ("auto", *ATLAS_IMAGES):
        raise InputError(f"atlas_image={o['atlas_image']!r} is not one of None, 'auto', "
                         f"{', '.join(repr(k) for k in ATLAS_IMAGES)}")
    return dict(unwrap=u, **o, uvbake=__version__)


def run(inputs: Any, out_dir: str | os.PathLike[str], client: Any = None, *, scheduler: str | None = None,
        workers: int | None = None, timeout_per_asset_s: float = DEFAULT_TIMEOUT_S, retries: int = 1,
        progress: bool = False, html: bool = True, **options: Any) -> Any:
    """Unwrap every asset of ``inputs`` into ``out_dir``, on Dask; return the summary table.

    Parameters
    ----------
    inputs : path or list of paths
        Mesh files, folders (searched recursively) and ``.txt``/``.csv`` manifests
        (see :mod:`uvbake.batch.inputs`).
    out_dir : path
        Created if missing. Gets ``assets/<id>/`` per asset (outputs, ``report.json``, ``preview.png``,
        ``atlas.png``, and the marker ``status.json``), ``summary.parquet``, ``summary.csv`` and
        ``report.html``. Reusing it resumes: assets whose marker matches are not redone.
    client : distributed.Client, optional
        Where to run. Default: ``scheduler`` if given, else a ``LocalCluster`` of ``workers`` processes
        (default: the usable cores) with one thread each, closed at the end. ``client="local"`` runs a
        plain loop in this process (no Dask; the benchmark's baseline).
    timeout_per_asset_s : float
        Time limit per asset, from the fork of its process to its end, file writes and thumbnails
        included (a manifest's ``timeout_s`` overrides it).
    retries : int
        Dask retries of a task that raised (not of an asset that failed: that is recorded). Tasks on
        workers that died are rescheduled by Dask up to ``distributed.scheduler.allowed-failures``
        times (default 3), then recorded as ``lost``.
    progress : bool
        Show a progress bar over assets (on a terminal).
    **options
        ``alpha``, ``init``, ``backend``, ``tol``, ``max_iter``, ``seed``, ``texture_size_px``,
        ``gutter_px``, ``bake`` (None, "checker" (default), "vertex-colors"), ``auto_cut``, ``repair``,
        ``guarantee``, ``continuation``, ``max_splits``, ``texel_density`` as in :func:`uvbake.unwrap`
        (``texel_density``: one texels-per-unit for every asset; each atlas then grows to fit unless
        ``texture_size_px`` is given too); ``format``
        ("obj" or "glb"), ``preview_size_px`` (0: none), ``atlas_image`` ("auto", "texture", "charts",
        None) and ``atlas_size_px``.

    Returns
    -------
    pyarrow.Table
        One row per asset (columns :data:`COLUMNS`), failures first. ``status`` is ``done``, ``cached``
        (skipped: done by an earlier run with the same input bytes and options), ``failed`` (an error,
        in ``error``), ``invalid`` (the atlas did not validate), ``timeout``, ``crashed`` or ``lost``.
        A table because it is what the summary files hold; ``.to_pylist()`` gives dicts.
    """
    _require_extra()
    opts = normalise_options(**options)
    _check_run_args(timeout_per_asset_s, workers)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"output {out} is a file; give a folder with -o")
    assets = collect(inputs, out_dir=out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "assets").mkdir(exist_ok=True)
    _remove_stale_staging(out / "assets")
    rows, todo = _plan(assets, out, opts, timeout_per_asset_s)
    bar = _bar(len(assets), len(rows)) if progress else None
    try:
        _execute(todo, rows, client, scheduler, workers, retries, progress, bar)
    finally:
        if bar is not None:
            bar.close()
    table = _table([rows[a.id] for a in assets])
    _write_summary(out, table)
    if html:
        from uvbake.batch.report import write_report

        write_report(out / "report.html", table.to_pylist(), out)
    return table


def _check_run_args(timeout_per_asset_s, workers):
    if not (timeout_per_asset_s and timeout_per_asset_s > 0):
        raise InputError(f"timeout_per_asset_s={timeout_per_asset_s!r} must be a positive number of seconds")
    if workers is not None and (int(workers) != workers or workers < 1):
        raise InputError(f"workers={workers!r} must be a whole number of at least 1")


def _plan(assets, out, opts, timeout_per_asset_s):
    """Rows of the assets a matching marker says are done (``cached``) and task specs for the rest."""
    okey = options_hash(opts)
    rows, todo = {}, []
    for a in assets:
        key = f"{file_hash(a.path)}-{okey}"
        asset_dir = out / "assets" / a.id
        marker = read_marker(asset_dir, key)
        if marker is not None:
            rows[a.id] = dict(marker["row"], status="cached", error=None)
        else:
            todo.append(dict(id=a.id, input=str(a.path), asset_dir=str(asset_dir.resolve()), key=key, options=opts,
                             timeout_s=float(a.timeout_s or timeout_per_asset_s)))
    return rows, todo


def _execute(todo, rows, client, scheduler, workers, retries, progress, bar):
    """Run the task specs ``todo`` into ``rows``: a plain loop (``client="local"``) or on Dask."""
    if not todo:
        return
    if client == "local":
        for spec in todo:
            try:
                rows[spec["id"]] = process(spec)
            except Exception as exc:  # noqa: BLE001 - recorded like a task Dask could not run
                rows[spec["id"]] = _lost(spec, exc)
            if bar is not None:
                bar.update(1)
        return
    own = None
    try:
        if client is None:
            client = own = _client(scheduler, workers)
        if progress:
            _print_dashboard(client)
        _run_dask(client, todo, rows, retries, bar)
    finally:
        if own is not None:
            cluster = getattr(own, "cluster", None)
            own.close()
            if cluster is not None:
                cluster.close()


def _require_extra():
    from uvbake.errors import UvbakeError

    try:
        import distributed  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as exc:
        raise UvbakeError(f"uvbake batch needs dask.distributed and pyarrow ({exc}); install them with "
                          "pip install 'uvbake[batch]'") from None


def _run_dask(client, todo, rows, retries, bar):
    import uuid

    from distributed import as_completed

    run_id = uuid.uuid4().hex[:8]       # a rerun's tasks never meet an earlier run's results held by the scheduler
    futures = {client.submit(process, spec, key=f"uvbake-batch-{run_id}-{spec['key'][:12]}-{spec['id']}",
                             pure=False, retries=retries): spec for spec in todo}
    for fut in as_completed(futures):
        spec = futures[fut]
        try:
            rows[spec["id"]] = fut.result()
        except Exception as exc:  # noqa: BLE001 - the task itself could not run (its worker kept dying, or a bug)
            rows[spec["id"]] = _lost(spec, exc)
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(_counts(rows), refresh=False)


def _lost(spec, exc):
    """The row (and, where the folder allows, the marker) of an asset whose task could not run to its end."""
    line = (str(exc).strip().splitlines() or [""])[0]
    row = dict(asset=spec["id"], input=spec["input"], key=spec["key"], status="lost",
               error=f"{type(exc).__name__}: {line}"[:500])
    with contextlib.suppress(OSError):   # the folder itself may be what failed
        asset_dir = Path(spec["asset_dir"])
        asset_dir.mkdir(parents=True, exist_ok=True)
        (asset_dir / MARKER).unlink(missing_ok=True)
        write_marker(asset_dir, dict(status="lost", key=spec["key"], row=row, outputs={}))
    return row


def _client(scheduler, workers):
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="20s")
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({exc}); start one with "
                             "'dask scheduler' or check --scheduler") from None
    n = workers or len(os.sched_getaffinity(0))
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0")
    return Client(cluster)


def _print_dashboard(client):
    services = client.scheduler_info().get("services", {})
    if "dashboard" in services:
        print(f"uvbake batch: Dask dashboard at {client.dashboard_link}", file=sys.stderr)


def _remove_stale_staging(assets_dir: Path) -> None:
    """Half-written outputs of an interrupted run (never trusted; removed before anything runs)."""
    for d in assets_dir.rglob(f"{STAGING_PREFIX}*"):
        if d.is_dir():
            shutil.rmtree(d, ignore_errors=True)


def _bar(total, done):
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit="asset", desc="uvbake batch", disable=None, file=sys.stderr)


def _counts(rows):
    c = {}
    for r in rows.values():
        c[r["status"]] = c.get(r["status"], 0) + 1
    return " ".join(f"{k} {v}" for k, v in sorted(c.items()))


def _table(rows):
    import pyarrow as pa

    rows = sorted(rows, key=lambda r: (STATUS_ORDER.get(r["status"], -1), r["asset"]))
    cols = {c: [r.get(c) for r in rows] for c in COLUMNS}
    return pa.table(cols)


def _write_summary(out: Path, table: Any) -> None:
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    from uvbake.io.atomic import atomic_write

    buf = _io.BytesIO()
    pq.write_table(table, buf)
    with atomic_write(out / "summary.parquet", "wb") as fh:
        fh.write(buf.getvalue())
    buf = _io.BytesIO()
    pcsv.write_csv(table, buf)
    with atomic_write(out / "summary.csv", "wb") as fh:
        fh.write(buf.getvalue())


def exit_status(table: Any) -> int:
    """0 when every asset is done or cached, else 1."""
    return 0 if all(s in OK_STATUSES for s in table.column("status").to_pylist()) else 1
