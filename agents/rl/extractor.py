"""The policy's feature extractor for a task that observes the belief map.

stable-baselines3's ``CombinedExtractor`` flattens a float image such as ``belief_map`` (its CNN is
for uint8 pictures of 36 px and more), so a 4 x 32 x 32 map would enter the MLP as 4,096 unrelated
numbers. :class:`BeliefMapExtractor` reads ``belief_map`` with a small CNN and flattens every other
entry, as ``CombinedExtractor`` does:

    conv 4x4, 16 channels, stride 2, padding 1, ReLU      (32 x 32 -> 16 x 16)
    conv 4x4, 32 channels, stride 2, padding 1, ReLU      (16 x 16 -> 8 x 8)
    adaptive average pool to 4 x 4, linear 512 -> ``belief_features`` (64), ReLU

At 4 heading channels that is 9,264 weights in the convolutions and 32,832 in the linear layer,
whatever the map's size (the adaptive pool fixes the linear layer's input). Strided convolutions
rather than 3x3 convolutions with pooling: on one core a batch of 4 maps takes 0.38 ms forward
against 1.0 ms, a batch of 64 forward and back 11 ms against 29 ms, for a receptive field of the
same size. ``make bench`` measures the cost per training step (BENCHMARKS.md).
"""

from __future__ import annotations

from typing import Any

import torch as th
from gymnasium import spaces
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

#: the observation entry the CNN reads
KEY = "belief_map"


class BeliefMapExtractor(BaseFeaturesExtractor):
    """A small CNN on ``belief_map``, every other entry flattened; the features concatenated.

    Args:
        observation_space: a ``spaces.Dict`` with a ``belief_map`` entry of shape ``(channels, rows, cols)``.
        belief_features: the CNN's output size.
    """

    def __init__(self, observation_space: spaces.Dict, belief_features: int = 64) -> None:
        belief = observation_space.spaces.get(KEY)
        if not isinstance(belief, spaces.Box) or len(belief.shape) != 3:
            raise ValueError(f"BeliefMapExtractor needs a {KEY!r} Box of shape (channels, rows, cols), got {belief!r}")
        others = {key: sub for key, sub in observation_space.spaces.items() if key != KEY}
        super().__init__(observation_space, belief_features + sum(get_flattened_obs_dim(s) for s in others.values()))
        channels = belief.shape[0]
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, kernel_size=4, stride=2, padding=1),
            nn.ReLU(),
            nn.Conv2d(16, 32, kernel_size=4, stride=2, padding=1),
            nn.ReLU(),
            nn.AdaptiveAvgPool2d(4),
            nn.Flatten(),
            nn.Linear(32 * 4 * 4, belief_features),
            nn.ReLU(),
        )
        self._others = sorted(others)

    def forward(self, observations: dict[str, Any]) -> th.Tensor:
        parts = [self.cnn(observations[KEY])]
        parts += [th.flatten(observations[key], start_dim=1) for key in self._others]
        return th.cat(parts, dim=1)
