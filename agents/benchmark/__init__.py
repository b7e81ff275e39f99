"""``crowdloc benchmark``: one protocol, one league table of every localizer in every world at every crowd size.

- :mod:`.protocol`: the protocol (``configs/benchmark/v2.yaml``; v1 kept), its strict loader, its test
  seeds (disjoint from every other command's) and its digest;
- :mod:`.run`: the plan (worlds x localizers x policies x crowd sizes x seeds, with the lines of
  what was left out), the plug-ins (``--plugins``) and each episode's score;
- :mod:`.results`: the rows, the crowd sensitivity, ``results.json``, ``results.csv``, ``leaderboard.md``;
- :mod:`.plots`: error and failure share against crowd size, per world, and the overview figure;
- :mod:`.journal`: ``episodes.jsonl``, each scored episode as it finishes (``--resume``);
- :mod:`.cli`: :func:`run_cli`.

Its episodes are ``crowdloc eval``'s (:mod:`agents.evaluate`), on the protocol's seeds.

May import: ``envs``, ``localizers``, :mod:`agents.common`, :mod:`agents.policies`,
:mod:`agents.experiments`, :mod:`agents.rl`, :mod:`agents.evaluate`; never :mod:`agents.papers`,
:mod:`agents.tune`, :mod:`agents.cli`, :mod:`agents.demo`.
"""

from __future__ import annotations

from agents.benchmark.protocol import DEFAULT_PROTOCOL, RESERVED_BELOW, Protocol, WorldProtocol, load_protocol, protocol_digest

__all__ = ["DEFAULT_PROTOCOL", "RESERVED_BELOW", "Protocol", "WorldProtocol", "load_protocol", "protocol_digest"]
