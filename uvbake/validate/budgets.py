"""Work budgets of the overlap check.

Candidate pairs are never capped: they are decided exactly, chunk by chunk, so the verdict is always
exact. Only the *list* of confirmed overlapping pairs is capped (``MAX_OVERLAP_PAIRS``): past it the
layout is invalid for certain and the list is partial (``complete=False``). The raster budgets only
bound the overlap image and the sub-pixel classification. The other modules read
them as ``budgets.NAME`` at call time, so a test can lower them with ``monkeypatch.setattr``.
"""

MAX_SPAN_ROWS = 1 << 25  # triangle rows scanned by the raster
RAW_PAIRS_PER_FACE = 48  # pairs sharing a hash cell or a pixel, per pass: a valid atlas needs ~15
MIN_RAW_PAIRS = 1 << 22
MAX_CLAIMS = 1 << 22  # (pixel, triangle) claims expanded on multiply-claimed rows
MAX_OVERLAP_PAIRS = 1 << 21  # confirmed overlapping pairs listed; past it the layout is invalid anyway
CHUNK = 1 << 20  # elements per vectorised chunk (bounds temporary memory)
