"""Image comparison for texture-regression tests: a jitter-tolerant mean absolute difference and SSIM.

    result = compare_images(actual, golden, jitter_px=1)
    result.mad        # mean over pixels of the per-pixel difference (0..255), jitter-tolerant
    result.ssim       # mean SSIM (Wang et al. 2004, gaussian window sigma 1.5), jitter-tolerant
    result.diff       # (H,W) float32 per-pixel difference, mean over channels, jitter-tolerant

Jitter tolerance (``jitter_px = j``): the difference at a pixel is the smaller of the two one-sided
neighbourhood distances, each the minimum over offsets ``|o|_inf <= j`` of ``mean_c |A(p) - G(p+o)|``
(and symmetrically ``G`` against ``A``), taking the larger of the two sides so an extra or a missing
feature is never hidden. An edge that moved by up to ``j`` pixels (rasteriser rounding, a different
thread count in the baker, an anti-aliasing change) then costs nothing, a chart that moved further
costs its full contrast. With ``j = 0`` this is the plain per-pixel absolute difference.

SSIM is computed per channel on 0..255 values (K1 = 0.01, K2 = 0.03, an 11-tap gaussian window of
sigma 1.5 via ``scipy.ndimage.gaussian_filter``), averaged over channels; each pixel's value is the
largest over the golden shifted by ``|o|_inf <= j`` (so an edge or a chart displaced by up to ``j``
pixels is not penalised, a larger displacement or a changed texture is), then averaged over pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

SSIM_SIGMA = 1.5
SSIM_TRUNCATE = 3.5          # radius int(3.5 * 1.5 + 0.5) = 5: the 11x11 window of Wang et al.
SSIM_K1, SSIM_K2, SSIM_L = 0.01, 0.03, 255.0


@dataclass
class Comparison:
    """Result of :func:`compare_images`."""

    mad: float                  #: jitter-tolerant mean absolute difference, 0..255 levels
    ssim: float                 #: mean structural similarity, -1..1 (1 = identical)
    max_diff: float             #: largest jitter-tolerant per-pixel difference
    diff: np.ndarray            #: (H,W) float32 jitter-tolerant per-pixel difference (0..255)
    jitter_px: int

    def to_dict(self):
        return dict(mad=self.mad, ssim=self.ssim, max_diff=self.max_diff, jitter_px=self.jitter_px)


def as_image(obj) -> np.ndarray:
    """An (H,W,C) uint8 array (C = 1, 3 or 4) from a path, a PIL image or an array.

    Float arrays are read as values in [0, 1]; (H,W) arrays become (H,W,1).
    """
    if isinstance(obj, (str, Path)):
        from PIL import Image

        with Image.open(obj) as im:
            if im.mode not in ("L", "RGB", "RGBA"):
                im = im.convert("RGBA" if "A" in im.getbands() else "RGB")
            arr = np.asarray(im).copy()
    elif hasattr(obj, "getbands"):              # PIL image
        im = obj if obj.mode in ("L", "RGB", "RGBA") else obj.convert("RGB")
        arr = np.asarray(im).copy()
    else:
        arr = np.asarray(obj)
        if arr.dtype.kind == "f":
            if not np.all(np.isfinite(arr)):
                raise ValueError("image has NaN or infinite values; pass finite values in [0, 1]")
            arr = np.clip(np.rint(arr * 255.0), 0, 255).astype(np.uint8)
        elif arr.dtype == np.bool_:
            arr = arr.astype(np.uint8) * 255
        elif arr.dtype != np.uint8:
            if arr.size and (arr.min() < 0 or arr.max() > 255):
                raise ValueError(f"integer image values must be in 0..255, got {arr.min()}..{arr.max()}")
            arr = arr.astype(np.uint8)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4) or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"an image must be (H,W), (H,W,1), (H,W,3) or (H,W,4), got shape {arr.shape}")
    return np.ascontiguousarray(arr)


def _shifted(img, dy, dx):
    """``img`` translated so that out[p] = img[p + (dy, dx)], edges replicated."""
    h, w = img.shape[:2]
    ys = np.clip(np.arange(h) + dy, 0, h - 1)
    xs = np.clip(np.arange(w) + dx, 0, w - 1)
    return img[ys][:, xs]


def pixel_diff(a: np.ndarray, g: np.ndarray, jitter_px: int = 1) -> np.ndarray:
    """(H,W) float32 jitter-tolerant difference (mean over channels, 0..255) of two (H,W,C) uint8 images."""
    a16, g16 = a.astype(np.int16), g.astype(np.int16)
    if jitter_px <= 0:
        return _chan_mean(np.abs(a16 - g16))
    offsets = [(dy, dx) for dy in range(-jitter_px, jitter_px + 1) for dx in range(-jitter_px, jitter_px + 1)]
    big = np.int16(255 * a.shape[2])
    a_to_g = np.full(a.shape[:2], big, np.int16)
    g_to_a = np.full(a.shape[:2], big, np.int16)
    for dy, dx in offsets:
        np.minimum(a_to_g, np.abs(a16 - _shifted(g16, dy, dx)).sum(axis=2), out=a_to_g)
        np.minimum(g_to_a, np.abs(g16 - _shifted(a16, dy, dx)).sum(axis=2), out=g_to_a)
    return _chan_mean(np.maximum(a_to_g, g_to_a)[:, :, None], a.shape[2])


def _chan_mean(d, channels=None):
    """Per-pixel mean over channels of summed absolute differences, as float32 (H,W)."""
    if channels is None:
        channels = d.shape[2]
        d = d.sum(axis=2)
    else:
        d = d[:, :, 0]
    return (d.astype(np.float32) / np.float32(channels))


def _ssim_map(a: np.ndarray, g: np.ndarray) -> np.ndarray:
    """(H,W) SSIM map of two same-shape (H,W,C) images (values 0..255), averaged over channels."""
    from scipy.ndimage import gaussian_filter

    x = a.astype(np.float64)
    y = g.astype(np.float64)
    sig = (SSIM_SIGMA, SSIM_SIGMA, 0)           # no blur across channels

    def blur(z):
        return gaussian_filter(z, sig, truncate=SSIM_TRUNCATE, mode="reflect")

    mx, my = blur(x), blur(y)
    sxx = blur(x * x) - mx * mx
    syy = blur(y * y) - my * my
    sxy = blur(x * y) - mx * my
    c1 = (SSIM_K1 * SSIM_L) ** 2
    c2 = (SSIM_K2 * SSIM_L) ** 2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s.mean(axis=2)


def ssim(a: np.ndarray, g: np.ndarray, jitter_px: int = 0) -> float:
    """Mean SSIM of two same-shape (H,W,C) uint8 images, tolerant to local shifts up to ``jitter_px``.

    With ``jitter_px = j > 0`` each pixel's local SSIM is the largest over the golden shifted by
    ``|o|_inf <= j`` (edges replicated), so a chart or an edge displaced by up to ``j`` pixels scores
    as unchanged while anything displaced further, or changed, does not.
    """
    best = _ssim_map(a, g)
    for dy in range(-jitter_px, jitter_px + 1):
        for dx in range(-jitter_px, jitter_px + 1):
            if dy or dx:
                np.maximum(best, _ssim_map(a, _shifted(g, dy, dx)), out=best)
    return float(best.mean())


def compare_images(actual, golden, *, jitter_px: int = 1) -> Comparison:
    """Compare two images of the same size; see the module docstring for the measures."""
    a, g = as_image(actual), as_image(golden)
    if a.shape != g.shape:
        raise ValueError(f"image shapes differ: actual {a.shape}, golden {g.shape}")
    if isinstance(jitter_px, bool) or not isinstance(jitter_px, (int, np.integer)) or not 0 <= jitter_px <= 8:
        raise ValueError(f"jitter_px={jitter_px!r} must be a whole number of pixels from 0 to 8")
    d = pixel_diff(a, g, int(jitter_px))
    return Comparison(mad=float(d.mean()), ssim=ssim(a, g, int(jitter_px)), max_diff=float(d.max()),
                      diff=d, jitter_px=int(jitter_px))


def diff_image(actual, golden, diff: np.ndarray | None = None) -> np.ndarray:
    """An RGB picture of the difference: the golden faded to grey, differing pixels in red (x4)."""
    a, g = as_image(actual), as_image(golden)
    if diff is None:
        diff = pixel_diff(a, g, 0) if a.shape == g.shape else None
    gray = g[:, :, :3].astype(np.float64).mean(axis=2) if g.shape[2] >= 3 else g[:, :, 0].astype(np.float64)
    base = 128.0 + gray / 4.0
    out = np.repeat(base[:, :, None], 3, axis=2)
    if diff is not None:
        k = np.clip(diff.astype(np.float64) * 4.0, 0, 255) / 255.0
        out[:, :, 0] = out[:, :, 0] * (1 - k) + 255.0 * k
        out[:, :, 1] = out[:, :, 1] * (1 - k)
        out[:, :, 2] = out[:, :, 2] * (1 - k)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
