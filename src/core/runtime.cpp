#include "hlt/core/runtime.h"

#include <ATen/Context.h>
#include <ATen/Parallel.h>

#include "hlt/util/error.h"
#include "hlt/util/random.h"

namespace hlt {

void seed_torch(uint64_t seed) {
  at::manual_seed(derive_seed(seed, 0x70726368));
}

void set_torch_threads(int threads) {
  check(threads >= 1, "thread count must be >= 1, got {}", threads);
  at::set_num_threads(threads);
}

}  // namespace hlt
