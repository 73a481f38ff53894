#include "hlt/data/replay_buffer.h"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// MemAvailable from /proc/meminfo, in bytes; 0 if unknown.
double available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("MemAvailable:", 0) == 0) return std::stod(line.substr(13)) * 1024.0;
  return 0;
}

}  // namespace
namespace {

void copy_row(at::Tensor& t, int64_t row, const double* src) {
  float* dst = t.data_ptr<float>() + row * t.size(1);
  for (int64_t j = 0; j < t.size(1); ++j)
    dst[j] = static_cast<float>(src[j]);
}

}  // namespace

ReplayBuffer::ReplayBuffer(int64_t capacity, int64_t state_dim, int64_t action_dim, uint64_t seed)
    : capacity_(capacity), state_dim_(state_dim), action_dim_(action_dim), rng_(seed) {
  check(capacity > 0 && state_dim > 0 && action_dim > 0, "ReplayBuffer needs positive sizes");
  // Refused up front rather than failing inside the allocator (or later, swapping).
  const double bytes = static_cast<double>(capacity) * (2 * state_dim + 2 * action_dim + 2) * sizeof(float);
  const double available = available_memory_bytes();
  auto too_big = [&] {
    return fmt::format(
        "a replay buffer of {} transitions (state {}, action {}) needs {:.1f} GB, more than the {:.1f} GB "
        "of memory available; lower train.replay_capacity",
        capacity, state_dim, action_dim, bytes / 1e9, available / 1e9);
  };
  check(available <= 0 || bytes < 0.9 * available, "{}", too_big());
  const auto opts = torch::TensorOptions().dtype(torch::kFloat32);
  try {
    states_ = torch::zeros({capacity, state_dim}, opts);
    actions_ = torch::zeros({capacity, action_dim}, opts);
    rewards_ = torch::zeros({capacity, 1}, opts);
    next_states_ = torch::zeros({capacity, state_dim}, opts);
    next_actions_ = torch::zeros({capacity, action_dim}, opts);
    dones_ = torch::zeros({capacity, 1}, opts);
  } catch (const c10::Error&) {
    // A memory limit (ulimit -v, a cgroup) below what the machine reports as available.
    throw Error(
        fmt::format("cannot allocate a replay buffer of {} transitions ({:.1f} GB): out of memory; "
                    "lower train.replay_capacity",
                    capacity, bytes / 1e9));
  }
}

void ReplayBuffer::add(const double* state, const double* action, double reward, const double* next_state,
                       const double* next_action, bool done) {
  copy_row(states_, next_, state);
  copy_row(actions_, next_, action);
  copy_row(next_states_, next_, next_state);
  copy_row(next_actions_, next_, next_action);
  rewards_.data_ptr<float>()[next_] = static_cast<float>(reward);
  dones_.data_ptr<float>()[next_] = done ? 1.0f : 0.0f;
  next_ = (next_ + 1) % capacity_;
  size_ = std::min(size_ + 1, capacity_);
}

Batch ReplayBuffer::sample(int64_t batch_size, int64_t steps) {
  check(size_ > 0, "cannot sample from an empty replay buffer");
  check(batch_size > 0, "batch size must be positive, got {}", batch_size);
  check(steps > 0, "sequence length must be positive, got {}", steps);
  std::vector<int64_t> rows(static_cast<size_t>(batch_size * steps));
  if (steps == 1) {
    std::uniform_int_distribution<int64_t> pick(0, size_ - 1);
    for (int64_t& i : rows)
      i = pick(rng_);
    return gather(rows, 1);
  }
  const auto no_sequence = [&] {
    return fmt::format(
        "no {} consecutive transitions of one episode in a replay buffer of {} transitions "
        "(model.rollout_steps is "
        "longer than the stored episodes)",
        steps, size_);
  };
  check(size_ >= steps, "{}", no_sequence());
  const int64_t oldest = size_ == capacity_ ? next_ : 0;
  // Rejection sampling: a start is drawn uniformly and kept if its sequence stays in one episode.
  std::uniform_int_distribution<int64_t> pick(0, size_ - steps);
  auto starts_sequence = [&](int64_t p) {
    for (int64_t j = 0; j + 1 < steps; ++j)
      if (!continues(p + j)) return false;
    return true;
  };
  int64_t failures = 0;
  for (int64_t b = 0; b < batch_size; ++b) {
    int64_t p = pick(rng_);
    while (!starts_sequence(p)) {
      // Only checked after many misses, so a buffer where sequences are rare still samples them.
      if (++failures == 10000) {
        bool any = false;
        for (int64_t q = 0; q + steps <= size_ && !any; ++q)
          any = starts_sequence(q);
        check(any, "{}", no_sequence());
      }
      p = pick(rng_);
    }
    for (int64_t k = 0; k < steps; ++k)
      rows[static_cast<size_t>(k * batch_size + b)] = (oldest + p + k) % capacity_;
  }
  return gather(rows, steps);
}

bool ReplayBuffer::continues(int64_t p) const {
  const int64_t oldest = size_ == capacity_ ? next_ : 0;
  const int64_t row = (oldest + p) % capacity_, following = (oldest + p + 1) % capacity_;
  if (dones_.data_ptr<float>()[row] != 0.0f) return false;
  // A reset starts the next episode from a state that (almost surely) is not the last one reached.
  const float* reached = next_states_.data_ptr<float>() + row * state_dim_;
  const float* start = states_.data_ptr<float>() + following * state_dim_;
  return std::equal(reached, reached + state_dim_, start);
}

Batch ReplayBuffer::gather(const std::vector<int64_t>& rows, int64_t steps) const {
  // Rows copied by hand: the same values as six index_select calls, without their dispatch (6 samples per
  // agent step).
  const auto count = static_cast<int64_t>(rows.size());
  auto gather_field = [&](const at::Tensor& from) {
    const int64_t width = from.size(1);
    at::Tensor to = at::empty({count, width}, from.options());
    const float* src = from.data_ptr<float>();
    float* dst = to.data_ptr<float>();
    for (int64_t i = 0; i < count; ++i)
      std::copy_n(src + rows[static_cast<size_t>(i)] * width, width, dst + i * width);
    return to;
  };
  return {gather_field(states_),
          gather_field(actions_),
          gather_field(rewards_),
          gather_field(next_states_),
          gather_field(next_actions_),
          gather_field(dones_),
          steps};
}

Batch select_rows(const Batch& b, const at::Tensor& rows) {
  check(b.steps == 1, "select_rows takes a batch of single transitions, got sequences of {}", b.steps);
  return {b.states.index_select(0, rows),
          b.actions.index_select(0, rows),
          b.rewards.index_select(0, rows),
          b.next_states.index_select(0, rows),
          b.next_actions.index_select(0, rows),
          b.dones.index_select(0, rows),
          1};
}

Batch ReplayBuffer::all() const {
  torch::Tensor idx = (torch::arange(size_, torch::kInt64) + (size_ == capacity_ ? next_ : 0)) % capacity_;
  return {states_.index_select(0, idx),
          actions_.index_select(0, idx),
          rewards_.index_select(0, idx),
          next_states_.index_select(0, idx),
          next_actions_.index_select(0, idx),
          dones_.index_select(0, idx),
          1};
}

void ReplayBuffer::save(torch::serialize::OutputArchive& archive) const {
  // Only the filled rows are written, so a large, mostly empty buffer costs little.
  const int64_t rows = size_;
  archive.write("states", states_.narrow(0, 0, rows).clone());
  archive.write("actions", actions_.narrow(0, 0, rows).clone());
  archive.write("rewards", rewards_.narrow(0, 0, rows).clone());
  archive.write("next_states", next_states_.narrow(0, 0, rows).clone());
  archive.write("next_actions", next_actions_.narrow(0, 0, rows).clone());
  archive.write("dones", dones_.narrow(0, 0, rows).clone());
  archive.write("sizes", torch::tensor({capacity_, state_dim_, action_dim_, size_, next_}, torch::kInt64));
  std::ostringstream rng;
  rng << rng_;
  archive.write("rng", c10::IValue(rng.str()));
}

void ReplayBuffer::load(torch::serialize::InputArchive& archive) {
  torch::Tensor sizes;
  archive.read("sizes", sizes);
  check(sizes.numel() == 5, "replay buffer record is malformed");
  const int64_t* s = sizes.data_ptr<int64_t>();
  check(s[0] == capacity_ && s[1] == state_dim_ && s[2] == action_dim_,
        "replay buffer in checkpoint has capacity {} and dims ({}, {}); this run expects {} and ({}, {})",
        s[0], s[1], s[2], capacity_, state_dim_, action_dim_);
  const int64_t rows = s[3];
  check(rows >= 0 && rows <= capacity_ && s[4] >= 0 && s[4] < capacity_, "replay buffer record is malformed");
  auto read_into = [&](const char* key, torch::Tensor& dst) {
    torch::Tensor t;
    archive.read(key, t);
    check(t.dim() == 2 && t.size(0) == rows && t.size(1) == dst.size(1),
          "replay buffer field '{}' has a wrong shape", key);
    dst.narrow(0, 0, rows).copy_(t);
  };
  read_into("states", states_);
  read_into("actions", actions_);
  read_into("rewards", rewards_);
  read_into("next_states", next_states_);
  read_into("next_actions", next_actions_);
  read_into("dones", dones_);
  size_ = rows;
  next_ = s[4];
  c10::IValue rng;
  archive.read("rng", rng);
  std::istringstream in(rng.toStringRef());
  in >> rng_;
  check(!in.fail(), "replay buffer generator state is corrupt");
}

}  // namespace hlt
