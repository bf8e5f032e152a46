"""The common scale of a shape packing: searched for a fixed atlas, or an atlas grown for a fixed scale.

Every search packs uvbake.atlas.shapepack's rasterised footprints (ShapePacker) and keeps the packing
with the largest texel density that fits; the measurements behind the choices are in
docs/decisions/pack.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from uvbake.atlas.shapepack import ShapePacker, ShapePacking

# Swapped chart orders (fit_width's swaps): a bottom-left fill of 5-16 large charts is only as good as
# the order it places them in, and a hill climb on pair swaps of the best order finds much of what the
# best order would give. Each swap costs two strip packings, so the budget is a work count: one swap
# per FACES_PER_SWAP faces (about 5 % of the command's CPU) for up to SWAPS_COUNTED charts, past them
# per FACES_PER_SWAP * n / SWAPS_COUNTED faces (a strip packing's cost grows with the chart count),
# none below MIN_SWAPS (a climb that short rarely gains), at most MAX_SWAPS; past SWAPS_UP_TO charts a
# swap changes little. Measurements: docs/decisions/pack.md (2026-12-01, sixth session; 2026-12-03,
# fourth session).
SWAPS_UP_TO = 16
SWAPS_COUNTED = 8
MIN_SWAPS = 4
MAX_SWAPS = 12
FACES_PER_SWAP = 1500


def swap_budget(n: int, faces: int) -> int:
    """Swapped chart orders fit_width may try for ``n`` charts (more than 4: fewer try every base angle
    instead) of ``faces`` triangles in all."""
    if n > SWAPS_UP_TO:
        return 0
    k = min(MAX_SWAPS, int(faces * SWAPS_COUNTED // (FACES_PER_SWAP * max(n, SWAPS_COUNTED))))
    return k if k >= MIN_SWAPS else 0


def _coarse_factor(width, height, coarse_px):
    """The power of two ``c`` making the long side about ``coarse_px`` (the short side at least 32)."""
    c = 1
    while (max(width, height) // (2 * c) >= coarse_px and min(width, height) // (2 * c) >= 32
           and width % (2 * c) == 0 and height % (2 * c) == 0):
        c *= 2
    return c


def resolving_coarse_px(packer: ShapePacker, width: int, height: int, coarse_px: int, small_texels: float) -> int:
    """``coarse_px``, or twice that when the charts holding most of the area are small on that raster: the
    area-weighted median chart, at the density filling the atlas, under ``small_texels`` coarse texels a
    side. There the coarse footprints' rounding (a texel or two a side) is a large part of every chart,
    so the coarse search settles on a density its full-resolution layout leaves far short of the top."""
    if packer.area.sum() <= 0:
        return coarse_px
    small = filling_side(packer, width, height) / _coarse_factor(width, height, coarse_px) < small_texels
    return 2 * coarse_px if small else coarse_px


def median_side(packer: ShapePacker, density: float) -> float:
    """Texels a side of the area-weighted median chart (the square root of its area) at ``density``."""
    a = packer.area
    side = np.sqrt(a) * density
    order = np.argsort(side, kind="stable")
    return float(side[order][min(int(np.searchsorted(np.cumsum(a[order]), 0.5 * a.sum())), len(a) - 1)])


def filling_side(packer: ShapePacker, width: int, height: int) -> float:
    """median_side at the density that would fill a ``width x height`` atlas (0 for charts of no area)."""
    total = float(packer.area.sum())
    return median_side(packer, np.sqrt(width * height / total)) if total > 0 else 0.0


def _search(packer, width, height, g, lo, lo_pack, hi, s, max_packs, rel_tol):
    """Bracketed search for the largest feasible density: the height a trial needs steers the next one
    (at a fixed width the height grows like density^2), kept inside the bracket [lo, hi]."""
    for _ in range(max_packs):
        if lo is not None and hi is not None and hi <= lo * (1 + rel_tol):
            break
        p = packer.pack(s, width, None, g, give_up_above=height)
        if p is not None and p.complete and p.height_used <= height:
            lo, lo_pack = s, p
        else:
            hi = s
        guess = s * np.sqrt(height / p.height_used) if p is not None else 0.8 * s
        if lo is None:
            s = min(guess, 0.9 * s)
        elif hi is None:
            s = max(guess, 1.05 * s)
        else:
            s = float(np.clip(guess, lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)))
    return lo, lo_pack


def fit_scale(packer: ShapePacker, width: int, height: int, gutter_px: int, *, coarse_px: int = 256,
              rel_tol: float = 4e-3, coarse_tol: float | None = None, fine_packs: int = 2, guess: float | None = None,
              beat_guess: bool = False, fine_side: int | None = None, finer_last: bool = False) -> ShapePacking | None:
    """Largest common density (texels per world unit) at which the charts fill a ``width x height`` atlas.

    Each trial packs an unbounded strip ``width`` texels wide and is feasible when it needs at most
    ``height`` rows. The search runs first on a raster ``c`` times coarser (``c`` a power of two making
    the long side about ``coarse_px``, the short side at least 32; gutter ``ceil(gutter_px / c)`` coarse texels): a coarse packing
    scaled by ``c`` is a valid full-resolution packing (coarse footprints cover the fine ones, gutters
    and margins only grow), so it is the fallback; then at most ``fine_packs`` full-resolution trials
    look for a larger density (on a raster ``f`` times coarser than the atlas, ``f`` the least power of two
    making its long side at most ``fine_side``; None: the atlas's own). ``guess`` (a density, e.g. a box
    packer's) starts the search; with
    ``beat_guess`` and no full-resolution trials, a first trial failing at ``guess`` ends it (None: the
    search would only find lower densities). With ``finer_last`` (for tiny charts) the first
    full-resolution trial is made on a raster twice as fine as the atlas instead, aimed higher by what
    the finer rounding saves (:func:`_finer_gain`); the atlas's own trials follow only if it fails.
    Returns a ShapePacking at full resolution, or None if nothing fits.
    """
    g = int(gutter_px)
    area = float(packer.area.sum())
    c = _coarse_factor(width, height, coarse_px)
    top = np.sqrt(width * height / area) if area > 0 else 1.0
    cw, ch, cg = width // c, height // c, -(-g // c)
    if c == 1 or fine_packs == 0:
        coarse_tol = rel_tol
    elif coarse_tol is None:
        coarse_tol = 2.5 * rel_tol                                              # the fine trials refine it
    start = 0.75 * top if guess is None else min(guess, top)
    lo, p, hi = None, None, top / c
    if beat_guess and guess is not None:
        s0 = start / c
        p0 = packer.pack(s0, cw, None, cg, give_up_above=ch)
        if p0 is not None and p0.complete and p0.height_used <= ch:
            lo, p, start = s0, p0, s0 * min(max(np.sqrt(ch / p0.height_used), 1 + 2 * coarse_tol), top / s0) * c
        elif fine_packs == 0 or c == 1:
            return None
        else:
            hi = s0
    lo, p = _search(packer, cw, ch, cg, lo, p, hi, start / c, 16, coarse_tol)
    if lo is None:                                 # halve until something fits (tiny atlas, big gutter)
        lo, p = _halved(packer, 0.75 * top / c, cw, ch, cg)
        if lo is None:
            return None
    f = 1 if fine_side is None else _fine_factor(width, height, fine_side)
    if f >= c or fine_packs == 0:
        return ShapePacking(density=lo * c, rotation=p.rotation, offset=p.offset * c, height_used=p.height_used * c)
    return _finer(packer, width, height, g, lo, p, c // f, f, top, fine_packs, rel_tol, finer_last and f == 1)


#: When the trial on the twice finer raster fails, the atlas-raster trial after it aims this far under
#: the density the failed trial's height says the finer raster holds, taken back to the atlas's raster
#: (:func:`_finer_gain`; measured in docs/decisions/pack.md).
AIM_MARGIN = 0.995


def _finer_gain(packer, density, g):
    """The density a raster twice as fine as the atlas adds, as a factor: a chart's footprint and its
    gutter's dilation round it up by about a texel a side, half a texel on the finer raster, so a chart
    ``s`` texels wide (the area-weighted median) with gutter ``g`` needs (s + g + 1) / (s + g + 1/2)
    less room each way (the model against measured kits: docs/decisions/pack.md)."""
    s = median_side(packer, density)
    return (s + g + 1.0) / (s + g + 0.5)


def _twice_finer(packer, width, height, g, density):
    """One trial at ``density`` (texels of the atlas per unit) times :func:`_finer_gain`, on a raster twice
    as fine as the atlas (gutter and margins 2 g fine texels: every distance halves back), returned at
    the atlas's resolution, and None; when it does not fit, None and the density (atlas texels per
    unit, on the finer raster) its height says would fit (height grows as density squared), or None."""
    s = 2.0 * density * _finer_gain(packer, density, g)
    p = packer.pack(s, 2 * width, None, 2 * g, give_up_above=2 * height)
    if p is None or not p.complete or p.height_used > 2 * height:
        return None, (None if p is None else 0.5 * s * np.sqrt(2 * height / p.height_used))
    return ShapePacking(density=p.density / 2, rotation=p.rotation, offset=p.offset / 2,
                        height_used=-(-p.height_used // 2)), None


def _halved(packer, s, width, height, g):
    """(density, packing) of the first of s/2, s/4, ... (30 halvings at most) that fits; (None, None)."""
    for _ in range(30):
        s *= 0.5
        p = packer.pack(s, width, None, g)
        if p is not None and p.height_used <= height:
            return s, p
    return None, None


def _finer(packer, width, height, g, lo, p, k, f, top, fine_packs, rel_tol, twice_finer=False):
    """fit_scale's last trials, on a raster ``f`` times coarser than the atlas: from the coarse layout
    ``p`` (density ``lo``, made ``k`` times coarser still), returned at the atlas's resolution. With
    ``twice_finer`` (``f`` = 1) one trial on a raster twice as fine comes first (:func:`_twice_finer`);
    when it fails, the atlas-raster trial aims by its height (AIM_MARGIN), not 3 % over the coarse
    density, and is skipped when that aim does not beat the coarse layout."""
    aim = lo * k * 1.03
    if twice_finer:
        q, held = _twice_finer(packer, width, height, g, aim)
        if q is not None:
            return q
        if held is not None:        # what the finer raster's height says it holds, on the atlas's raster
            aim = AIM_MARGIN * held / _finer_gain(packer, held, g)
    # the coarse layout on the fine raster: scaled by k, still valid
    best = ShapePacking(density=lo * k, rotation=p.rotation, offset=p.offset * k, height_used=p.height_used * k)
    p = best if aim <= lo * k * (1 + rel_tol) else _search(packer, width // f, height // f, -(-g // f), lo * k, best,
                                                           top / f, aim, fine_packs, rel_tol)[1]
    return ShapePacking(density=p.density * f, rotation=p.rotation, offset=p.offset * f, height_used=p.height_used * f,
                        complete=p.complete)


def _fine_factor(width, height, side):
    """The least power of two ``f`` with ``max(width, height) / f <= side``."""
    f = 1
    while max(width, height) // f > side:
        f *= 2
    return f


def scale_to_border(packer: ShapePacker, p: ShapePacking, width: int, height: int, gutter_px: int, c: int = 1,
                    coarse_gutter: int | None = None) -> ShapePacking | None:
    """The packing ``p`` (made on a raster ``c`` times coarser with gutter ``coarse_gutter``) scaled about
    the atlas origin until a chart meets the border margin of a ``width x height`` atlas; None when the
    scaled layout would break the gutter.

    Scaling a layout by ``k`` (density and offsets alike) multiplies every distance by ``k``: gaps of at
    least ``c * coarse_gutter`` texels become ``k c coarse_gutter >= gutter_px`` when ``k`` is large
    enough; the layout's box is then moved to the margin ``ceil(gutter_px / 2)`` (a translation keeps
    every distance). So a layout packed small, in any strip, is a valid packing once scaled; at ``c = 1``
    this takes back the slack the conservative footprints and the coarse margins leave.
    """
    g = int(gutter_px)
    cg = g if coarse_gutter is None else int(coarse_gutter)
    m = (g + 1) // 2
    lo, hi = _layout_box(packer, p)
    # the layout's box [lo, hi] (coarse texels) scaled by c k and moved to start at the margin m
    k_fit = float(np.min((np.array([width, height], float) - 2 * m) / np.maximum(c * (hi - lo), 1e-300)))
    k = k_fit * (1.0 - 1e-9)                 # rounding must never push a chart past the margin
    # the box moved to m plus a hair (rounding of the translation must not put a vertex below m; the
    # 1e-9 taken off k leaves more room than that at the far side)
    m_low = m + 1e-10 * max(width, height)
    if k * c * cg < g * (1 + 1e-9) or k <= 0:
        if c != 1 or k_fit < 1 - 1e-9:       # a layout larger than the atlas (a strip taller than it)
            return None
        if k_fit < 1 + 1e-9:                 # p fills the atlas already: p itself (placed inside its strip)
            return p
        return ShapePacking(density=p.density, rotation=p.rotation, offset=p.offset - lo + m_low,
                            height_used=int(np.ceil(hi[1] - lo[1] + 2 * m)), complete=p.complete)
    return ShapePacking(density=p.density * c * k, rotation=p.rotation, offset=(p.offset - lo) * c * k + m_low,
                        height_used=int(np.ceil((hi[1] - lo[1]) * c * k + 2 * m)), complete=p.complete)


def fit_width(packer: ShapePacker, width: int, height: int, gutter_px: int, guess: float, *, coarse_px: int = 256,
              packs: int = 5, floor: float | None = None, rounds: int = 2,
              order_packs: int = 2, swaps: int = 0) -> ShapePacking | None:
    """Largest common density found by packing the charts once rasterised, in strips of several widths.

    The charts are rasterised once, ``c`` times coarser than the atlas (as in fit_scale), at a density
    a little under ``guess``; each trial packs that raster in a strip of another width and scales the
    layout up to the atlas (scale_to_border: every trial that fits is a valid packing, no trial is
    wasted on a density that does not fit, and the footprints are reused). The next width steers the
    layout's aspect towards the atlas's. When no width fits, the density is lowered by 0.8 and the
    widths tried again; ``rounds - 1`` more rounds start at 0.95 of the best density found. With
    ``floor`` (a density to beat) a round stops after two trials below it. Then each other chart
    order of the packer (``packer.orders``) gets ``order_packs`` trials on the best round's raster,
    from its best width; then up to ``swaps`` orders more, each the best order with two charts swapped
    (:func:`_swap_search`). Returns the densest full-resolution ShapePacking, or None.
    """
    g = int(gutter_px)
    c = _coarse_factor(width, height, coarse_px)
    cg = -(-g // c)
    best, d0 = None, 0.97 * guess / c
    for _ in range(40):                       # a density too high for every width: lower it
        best, w = _width_trials(packer, width, height, g, c, cg, d0, width // c, packs, floor)
        if best is not None or (floor is not None and 0.8 * d0 * c < floor):
            break
        d0 *= 0.8
    for _ in range(rounds - 1):               # again under the best density (another raster),
        if best is None:                      # from the best width scaled to it, two trials
            break
        d1 = 0.95 * best.density / c
        q, w1 = _width_trials(packer, width, height, g, c, cg, d1, int(round(w * d1 / d0)), 2, floor)
        if q is None or q.density <= best.density:
            break
        best, d0, w = q, d1, w1
    if best is None:
        return None
    best_order = packer.orders[0]
    for order in packer.orders[1:] if order_packs else []:     # the same raster, other chart orders
        q, w1 = _width_trials(packer, width, height, g, c, cg, d0, w, order_packs, floor, order=order)
        if q is not None and q.density > best.density:
            best, best_order, w = q, order, w1
    if swaps and order_packs:
        best = _swap_search(packer, width, height, g, c, cg, d0, w, best, best_order, swaps, order_packs)
    return best


def _swap_search(packer, width, height, g, c, cg, d0, w, best, order, evals, packs):
    """First-improvement hill climb on the chart order: orders that swap two charts of the best one
    (front pairs first: the big charts) are packed (``packs`` trials each, from the best width) until one
    is denser, which becomes the best; at most ``evals`` orders in all. A bottom-left fill of a few large
    charts is as good as the order it places them in, and neighbouring orders are often far apart
    (docs/decisions/pack.md); returns the densest packing found."""
    n = len(order)
    tried = {tuple(int(i) for i in o) for o in packer.orders}
    used = 0
    while used < evals:
        improved = False
        for i, j in ((i, j) for i in range(n - 1) for j in range(i + 1, n)):
            cand = np.array(order)
            cand[[i, j]] = cand[[j, i]]
            key = tuple(int(k) for k in cand)
            if key in tried:
                continue
            tried.add(key)
            used += 1
            q, w1 = _width_trials(packer, width, height, g, c, cg, d0, w, packs, best.density, order=cand)
            if q is not None and q.density > best.density:
                best, order, w, improved = q, cand, w1, True
            if improved or used >= evals:
                break
        if not improved:
            break
    return best


def _reach(packer, p, width, height, g, c):
    """The density the coarse layout ``p`` would reach scaled to the atlas, ignoring the gutter."""
    lo, hi = _layout_box(packer, p)
    m = (int(g) + 1) // 2
    return float(p.density * c * np.min((np.array([width, height], float) - 2 * m) / np.maximum(c * (hi - lo), 1e-300)))


def _layout_box(packer, p):
    """Lower and upper corner of the box around every chart of the packing ``p`` (its texels), from the
    charts' convex hull vertices (the extremes of a rotated chart are hull vertices), all charts at once."""
    P, cid = packer.hull_points()
    co, si = np.cos(p.rotation)[cid], np.sin(p.rotation)[cid]
    x = p.density * (P[:, 0] * co - P[:, 1] * si) + p.offset[cid, 0]
    y = p.density * (P[:, 0] * si + P[:, 1] * co) + p.offset[cid, 1]
    return np.array([x.min(), y.min()]), np.array([x.max(), y.max()])


def _width_trials(packer, width, height, g, c, cg, d0, w, packs, floor, order=None):
    """fit_width's trials at one coarse density ``d0`` from strip width ``w``: the densest scaled
    layout (or None) and its strip width. Widths move by 0.8 % at least, else the trials stop."""
    cw, ch = width // c, height // c
    best, misses, best_w = None, 0, w
    tried = set()
    for _ in range(packs):
        w = int(min(max(w, 8), cw))
        if w in tried:
            break
        tried.add(w)
        p = packer.pack(d0, w, None, cg, give_up_above=4 * ch, order=order)
        q = None if p is None or not p.complete else scale_to_border(packer, p, width, height, g, c, cg)
        if q is not None and (best is None or q.density > best.density):
            best, best_w = q, w
        if floor is not None and (q is None or q.density <= floor):
            misses += 1
            reach = _reach(packer, p, width, height, g, c) if p is not None and p.complete else 0.0
            if (misses >= 2 or reach < 0.95 * floor) and (best is None or best.density <= floor):
                break                         # far below the density to beat, or twice below it
        if p is None:                         # a chart wider than the strip
            w = int(np.ceil(w * 1.1))
            continue
        # steer the aspect of the layout (height_used x w) to the atlas's
        ratio = (p.height_used / max(w, 1)) / (ch / cw)
        step = float(np.clip(np.sqrt(ratio), 0.9, 1.1))
        if abs(step - 1.0) < 0.008:
            break
        w = int(round(w * step))
    return best, best_w


def grow_atlas(packer: ShapePacker, g: int, density: float, quantum: int, aspect: str,
               grow_side: int) -> tuple[int, int, ShapePacking]:
    """A growing atlas at a fixed ``density`` (sides multiples of ``quantum``; square, or with ``aspect``
    "free" the rectangle of fewest texels): (W, H, ShapePacking). An atlas expected over ``grow_side``
    texels a side is grown on a raster ``c`` times coarser (a power of two; gutter ceil(g / c), sides in
    quanta of quantum / c): the layout scaled by ``c`` is valid, as fit_scale's coarse layouts are, and
    the search costs as for an atlas of ``grow_side`` (docs/decisions/pack.md)."""
    from uvbake.errors import InputError

    side = np.sqrt(float(packer.area.sum()) / 0.8) * density           # the expected side
    c = _fine_factor(side, side, grow_side)
    cg, cd, cq, top = -(-g // c), density / c, max(1, quantum // c), 16384 // c
    if aspect == "free":
        W, H, p = grow_rectangle(packer, cg, cd, quantum=cq, max_side=top)
        if W is None:
            raise InputError(f"texel_density={density:g} needs a texture over 16384 texels a side; lower "
                             f"texel_density")
        return W * c, H * c, _scaled(p, c)
    W, p = grow_square(packer, cg, cd, quantum=cq, max_side=top)
    if W is None:
        raise InputError(f"texel_density={density:g} needs a texture over 16384 texels a side ({p * c} at "
                         f"least); lower texel_density")
    return W * c, W * c, _scaled(p, c)


def _scaled(p, c):
    """The ShapePacking ``p`` made on a raster ``c`` times coarser, at the atlas's resolution."""
    return p if c == 1 else ShapePacking(density=p.density * c, rotation=p.rotation, offset=p.offset * c,
                                         height_used=p.height_used * c, complete=p.complete)


def grow_square(packer: ShapePacker, gutter_px: int, density: float, *, quantum: int = 4,
                max_side: int = 16384) -> tuple[int | None, Any]:
    """Smallest square side (a multiple of ``quantum``) whose strip holds every chart at ``density``.

    Returns (side, ShapePacking) or (None, side needed at least) when it exceeds ``max_side``.
    """
    g = int(gutter_px)
    area_px = float(packer.area.sum()) * density * density
    side = int(quantum * np.ceil(np.sqrt(area_px / 0.8) / quantum))
    for _ in range(64):
        if side > max_side:
            return None, side
        p = packer.pack(density, side, None, g)
        if p is not None and p.height_used <= side:
            return side, p
        need = 1.25 * side if p is None else max(side + quantum, np.sqrt(side * p.height_used))   # None: too narrow
        side = int(quantum * np.ceil(need / quantum))
    return None, side


def grow_rectangle(packer: ShapePacker, gutter_px: int, density: float, *, quantum: int = 4,
                   max_side: int = 16384) -> tuple[Any, ...]:
    """Smallest-area ``width x height`` atlas (sides multiples of ``quantum``) holding every chart at
    ``density``: strips of widths ``sqrt(area) * 2^k`` (k = 0..6, at most ``max_side``) are packed (a
    strip stops once it needs more texels than the best so far) and the one needing the fewest texels
    wins (ties: the squarer). Returns (width, height, ShapePacking) or (None, None, None) when no strip
    fits within ``max_side``.
    """
    g = int(gutter_px)
    root = np.sqrt(float(packer.area.sum()) * density * density)
    widths = sorted({int(quantum * np.ceil(min(max(root * 2.0 ** k, 64), max_side) / quantum)) for k in range(7)})
    best = None
    for w in widths:                          # at most seven strips
        limit = max_side if best is None else min(max_side, best[0][0] // w)
        p = packer.pack(density, w, None, g, give_up_above=limit)
        if p is None or not p.complete:
            continue
        h = int(quantum * np.ceil(p.height_used / quantum))
        if h > max_side:
            continue
        key = (w * h, abs(np.log(w / h)))
        if best is None or key < best[0]:
            best = (key, w, h, p)
    return (None, None, None) if best is None else best[1:]
