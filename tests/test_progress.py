"""The CLI's progress line: charts solved and the running LM iteration (energy, gradient), no rate."""

import io
import re

from uvbake.cli.progress import Progress


class _Terminal(io.StringIO):
    def isatty(self):                     # tqdm draws only on a terminal
        return True

def test_progress_shows_charts_and_iterations_without_rate():
    buf = _Terminal()
    p = Progress(file=buf)
    p.bar.mininterval = 0                 # draw every update (the default throttles to 10 per second)
    p.stage("charts", 1, 1)
    p.stage("solve", 3, 8)
    p.iteration(dict(iteration=12, energy=0.2313, grad_norm=4.2e-5))
    p.stage("iterate", 12, 1000)          # the atlas pipeline's per-iteration stage: no effect on the count
    p.iteration(dict(iteration=13, energy=0.2311, grad_norm=3.0e-6))
    text = buf.getvalue()
    assert "uvbake solve: 3/8 charts" in text
    assert "LM iter 13: F 0.231, |grad| 3.0e-06" in text
    assert not re.search(r"\d\s*(s/chart|chart/s|it/s|s/it)", text)        # no rate anywhere
    p.stage("solve", 8, 8)
    p.close()
    assert "8/8 charts" in buf.getvalue()

def test_progress_counts_charts_placed_while_packing():
    buf = _Terminal()
    p = Progress(file=buf)
    p.bar.mininterval = 0
    p.stage("solve", 8, 8)
    p.stage("pack", 64, 300)               # the running shape packing's charts placed
    assert "uvbake pack: 64/300 charts" in buf.getvalue()
    p.stage("pack", 1, 1)
    p.close()


def test_quiet_progress_writes_nothing():
    buf = _Terminal()
    p = Progress(quiet=True, file=buf)
    p.stage("solve", 1, 2)
    assert p.iteration(dict(iteration=1, energy=1.0, grad_norm=1.0)) is None
    p.close()
    assert buf.getvalue() == ""
