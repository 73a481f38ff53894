// hlt::ReplayBuffer: a fixed-capacity ring buffer of transitions (s, a, r, s', a', done) held in contiguous
// float tensors, sampled uniformly from its own seeded generator. a' is the action taken at s' (the reward
// model's TD target needs it); done marks a true terminal state, never a time-limit cut.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <ATen/core/Tensor.h>

namespace torch::serialize {
class OutputArchive;
class InputArchive;
}  // namespace torch::serialize

namespace hlt {

// Transitions as rows: [R, n], [R, m], [R, 1], ... With steps > 1 the rows are `steps` consecutive
// transitions of each of B = R / steps sequences, time-major: row k * B + b is step k of sequence b, so
// rows [k * B, (k + 1) * B) are every sequence's k-th transition.
struct Batch {
  at::Tensor states, actions, rewards, next_states, next_actions, dones;
  int64_t steps = 1;
};

// The transitions of a batch of single transitions (steps 1) at `rows` ([R] int64 indices), in that order.
Batch select_rows(const Batch& batch, const at::Tensor& rows);

class ReplayBuffer {
 public:
  ReplayBuffer(int64_t capacity, int64_t state_dim, int64_t action_dim, uint64_t seed);

  // Appends one transition (overwriting the oldest when full). Pointers hold state_dim / action_dim values.
  void add(const double* state, const double* action, double reward, const double* next_state,
           const double* next_action, bool done);
  // `batch_size` transitions drawn uniformly with replacement. With steps > 1, `batch_size` sequences of
  // `steps` consecutive transitions of one episode (each transition's next state is the following one's
  // state and none but the last is terminal), their first transitions drawn uniformly among those that
  // start such a sequence. Throws hlt::Error if none does (every stored episode is shorter than `steps`).
  Batch sample(int64_t batch_size, int64_t steps = 1);
  // Rows [0, size()) in insertion order (oldest first): for behaviour cloning and tests.
  Batch all() const;

  int64_t size() const { return size_; }
  int64_t capacity() const { return capacity_; }
  int64_t state_dim() const { return state_dim_; }
  int64_t action_dim() const { return action_dim_; }

  // Contents, write position and generator state; load checks the sizes match.
  void save(torch::serialize::OutputArchive& archive) const;
  void load(torch::serialize::InputArchive& archive);

 private:
  int64_t capacity_, state_dim_, action_dim_;
  int64_t size_ = 0, next_ = 0;
  // One [capacity, width] float tensor per field: width n, m, 1, n, m, 1.
  at::Tensor states_, actions_, rewards_, next_states_, next_actions_, dones_;
  std::mt19937_64 rng_;

  Batch gather(const std::vector<int64_t>& rows, int64_t steps) const;
  // Whether the transition at insertion position p (0 oldest) continues into the one at p + 1.
  bool continues(int64_t p) const;
};

}  // namespace hlt
