// A replay buffer holding 40 random transitions of an n-state, m-action system (each next state a small step
// from its state, actions inside (-0.9, 0.9), an episode end every 13th transition), for the tests of
// learners, which need data of the right shapes rather than of a particular system.
#pragma once

#include <cstdint>

#include <torch/torch.h>

#include "hlt/data/replay_buffer.h"

namespace hlt::testing {

inline ReplayBuffer random_transitions(int64_t n, int64_t m, uint64_t seed) {
  ReplayBuffer buffer(64, n, m, seed);
  torch::manual_seed(7);
  for (int i = 0; i < 40; ++i) {
    const auto s = torch::randn({n}, torch::kFloat64), s2 = s + 0.1 * torch::randn({n}, torch::kFloat64);
    const auto a = torch::rand({m}, torch::kFloat64) * 1.8 - 0.9,
               a2 = torch::rand({m}, torch::kFloat64) * 1.8 - 0.9;
    buffer.add(s.data_ptr<double>(), a.data_ptr<double>(), 0.1 * i, s2.data_ptr<double>(),
               a2.data_ptr<double>(), i % 13 == 12);
  }
  return buffer;
}

}  // namespace hlt::testing
