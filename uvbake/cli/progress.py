"""The command line's progress display: charts solved or placed, and the running LM iteration of a long solve.

    uvbake solve: 3/8 charts [00:04], LM iter 12: F 2.31e-01, |grad| 4.2e-05

The pipeline calls ``stage(stage, done, total)`` per stage step and the solver calls
``iteration(info)`` per LM iteration (``info``: iteration, energy, grad_norm). No rate is shown:
charts differ in size by orders of magnitude, so charts per second predicts nothing. tqdm draws it
(on a terminal only: ``disable=None`` keeps pipes and CI logs clean) and throttles redraws.
"""

from __future__ import annotations

import sys
import time
from typing import IO, Any

#: tqdm format: stage, count, elapsed time, the last iteration; no rate and no ETA (see above)
BAR_FORMAT = "{desc}: {n_fmt}/{total_fmt} charts [{elapsed}]{postfix}"


class Progress:
    """Progress of one unwrap on stderr; every method is a no-op when ``quiet``."""

    def __init__(self, *, quiet: bool = False, file: IO[str] | None = None):
        self.bar: Any = None
        self._drawn = 0.0
        if not quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=1, desc="uvbake load", bar_format=BAR_FORMAT, disable=None, leave=False,
                            file=file or sys.stderr)
            if self.bar.disable:                 # not a terminal: nothing to draw
                self.bar = None

    def stage(self, stage: str, done: int, total: int) -> None:
        """Pipeline stage callback: the chart count follows "solve" (charts solved) and "pack" (charts
        placed by the running trial); other stages only rename the line."""
        if self.bar is None or stage == "iterate":      # iterations arrive through iteration()
            return
        self.bar.set_description_str(f"uvbake {stage}", refresh=False)
        if stage in ("solve", "pack"):
            self.bar.total = max(int(total), 1)
            self.bar.n = int(done)
            if done >= total:
                self.bar.set_postfix_str("", refresh=False)
        self.bar.refresh()

    def iteration(self, info: dict[str, Any]) -> None:
        """Solver callback: the last LM iteration's energy and gradient norm (returns None: never stops)."""
        if self.bar is None:
            return None
        self.bar.set_postfix_str(f"LM iter {info['iteration']}: F {info['energy']:.3g}, "
                                 f"|grad| {info['grad_norm']:.1e}", refresh=False)
        now = time.monotonic()                   # display only: redraw at most every mininterval seconds
        if now - self._drawn >= self.bar.mininterval:
            self._drawn = now
            self.bar.refresh()
        return None

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
