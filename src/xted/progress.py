"""Progress bars that do not count compilation: the first jitted call compiles for seconds to
minutes, so a bar's rate and ETA measured from its start would be off by that much."""

from __future__ import annotations

from tqdm.auto import tqdm


def restart_rate(bar: tqdm, description: str) -> None:
    """Measure ``bar``'s rate and ETA from now on (the steps so far count as done, not as timed),
    under ``description``; nothing for a disabled bar."""
    if bar.disable:
        return
    bar.set_description(description, refresh=False)
    bar.initial = bar.n  # tqdm's rate is (n - initial) / elapsed
    bar.start_t = bar.last_print_t = bar._time()
    bar.refresh()
