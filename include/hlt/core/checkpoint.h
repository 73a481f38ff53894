// Checkpoints: named modules, optimizers, tensors, integers and strings in one torch::save archive, written
// atomically (temporary file + rename) so a crash never leaves a truncated checkpoint. Loading checks every
// parameter's presence, shape and dtype and reports mismatches by name; a corrupt file is a clear error.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <ATen/core/Tensor.h>

namespace torch {
namespace nn {
class Module;
}
namespace optim {
class Optimizer;
}
namespace serialize {
class OutputArchive;
class InputArchive;
}  // namespace serialize
}  // namespace torch

namespace hlt {

class CheckpointWriter {
 public:
  CheckpointWriter();
  ~CheckpointWriter();
  void add_module(const std::string& name, const torch::nn::Module& module);
  void add_optimizer(const std::string& name, const torch::optim::Optimizer& optimizer);
  void add_tensor(const std::string& name, const at::Tensor& tensor);
  void add_int(const std::string& name, int64_t value);
  void add_string(const std::string& name, const std::string& value);
  // A nested archive for components that serialise themselves (the replay buffer).
  torch::serialize::OutputArchive& archive(const std::string& name);
  // Writes everything to `path` atomically.
  void save(const std::string& path);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class CheckpointReader {
 public:
  // Throws hlt::Error if the file is missing, corrupt, or not an hlt checkpoint.
  explicit CheckpointReader(const std::string& path);
  ~CheckpointReader();
  bool has(const std::string& name) const;
  // Copies the stored parameters and buffers into `module`; every name must exist with the same shape.
  void load_module(const std::string& name, torch::nn::Module& module);
  void load_optimizer(const std::string& name, torch::optim::Optimizer& optimizer);
  at::Tensor tensor(const std::string& name);
  int64_t get_int(const std::string& name);
  std::string get_string(const std::string& name);
  torch::serialize::InputArchive& archive(const std::string& name);
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hlt
