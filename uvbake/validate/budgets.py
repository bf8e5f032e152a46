"""Work budgets of the overlap check.

Past them the layout overlaps massively (e.g. every face mapped onto the whole texture) and the check
stops, reporting what it found and ``complete=False`` (never ``valid=True``). The other modules read
them as ``budgets.NAME`` at call time, so a test can lower them with ``monkeypatch.setattr``.
"""

MAX_SPAN_ROWS = 1 << 25  # triangle rows scanned by the raster
RAW_PAIRS_PER_FACE = 48  # pairs sharing a hash cell or a pixel, per pass: a valid atlas needs ~15
MIN_RAW_PAIRS = 1 << 22
MAX_CLAIMS = 1 << 22  # (pixel, triangle) claims expanded on multiply-claimed rows
CHUNK = 1 << 20  # elements per vectorised chunk (bounds temporary memory)
