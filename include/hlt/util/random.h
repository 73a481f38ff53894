// Seed derivation: one run seed fans out into independent, reproducible streams (torch, replay sampling,
// environment resets, evaluation) without the streams sharing state.
#pragma once

#include <cstdint>

namespace hlt {

// SplitMix64 finaliser: a well-mixed 64-bit hash, used to derive child seeds.
inline uint64_t mix_seed(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// The seed of stream `stream` under run seed `seed`.
inline uint64_t derive_seed(uint64_t seed, uint64_t stream) {
  return mix_seed(mix_seed(seed) ^ mix_seed(stream));
}

}  // namespace hlt
