"""Choose a trained policy on validation episodes: the one with the highest mean episode return.

The rule a task config with ``layouts`` fixes before training: evaluate every checkpoint of the run
(``crowdloc eval --conditions CONFIG --layout-split validation --first-seed 1000 --policies
ppo:CKPT ...``) and keep the one whose episodes' mean return is highest (the return is the task's
own objective; ties go to the later checkpoint, listed later).

Run: ``python -m agents.evaluate.choose EVAL_DIR`` prints each policy's mean return over its
episodes and the chosen one.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections import defaultdict
from pathlib import Path

from core.schema import ConfigError


def mean_returns(episodes_csv: Path) -> dict[str, tuple[float, int]]:
    """Per policy (in the file's order): the mean episode return and the episode count.

    Raises:
        ConfigError: a missing file, or one without ``policy`` and ``episode_return`` columns.
    """
    if not episodes_csv.is_file():
        raise ConfigError(f"{episodes_csv}: no such file (give the folder of a crowdloc eval run)")
    returns: dict[str, list[float]] = defaultdict(list)
    with episodes_csv.open(newline="") as f:
        reader = csv.DictReader(f)
        if not {"policy", "episode_return"} <= set(reader.fieldnames or ()):
            raise ConfigError(f"{episodes_csv}: expected the columns policy and episode_return of crowdloc eval's episodes.csv")
        for row in reader:
            returns[row["policy"]].append(float(row["episode_return"]))
    return {policy: (math.fsum(r) / len(r), len(r)) for policy, r in returns.items()}


def chosen(means: dict[str, tuple[float, int]]) -> str:
    """The policy with the highest mean return; of equal ones, the last listed."""
    best = max(mean for mean, _ in means.values())
    return [policy for policy, (mean, _) in means.items() if mean == best][-1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("eval_dir", type=Path, help="the --out folder of a crowdloc eval run on validation episodes")
    args = parser.parse_args(argv)
    means = mean_returns(args.eval_dir / "episodes.csv")
    for policy, (mean, count) in means.items():
        print(f"{policy}: mean return {mean:.2f} over {count} episodes")
    print(f"chosen: {chosen(means)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
