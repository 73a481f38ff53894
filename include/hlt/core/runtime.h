// Process-wide LibTorch settings: seeding and thread count. One seed, one thread -> the same numbers.
#pragma once

#include <cstdint>

namespace hlt {

// Seeds LibTorch's default generator with a stream derived from `seed`.
void seed_torch(uint64_t seed);
// Sets LibTorch's intra-op (and OpenMP/BLAS) thread count. The project's networks are small: one thread
// is fastest for batch-1 calls and is the default for reproducibility.
void set_torch_threads(int threads);

}  // namespace hlt
