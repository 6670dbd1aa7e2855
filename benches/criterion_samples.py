"""Reading criterion's saved samples, for the scripts beside this file."""

import json
import os
import statistics


def median_ns(folder):
    """The median of the per-iteration times (ns) of the samples saved in
    criterion's `folder` (a benchmark's `new`), or None where it holds none:
    the statistic tinybvh's bench reports, where criterion's printed
    estimate is a regression slope that one slow sample pulls down."""
    try:
        with open(os.path.join(folder, "sample.json")) as f:
            sample = json.load(f)
    except (OSError, ValueError):
        return None
    return statistics.median(t / n for t, n in zip(sample["times"], sample["iters"]))
