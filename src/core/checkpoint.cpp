#include "hlt/core/checkpoint.h"

#include <map>

#include <torch/torch.h>

#include "hlt/util/checksum.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

constexpr const char* kFormatKey = "hlt_format";
// 2: twin critics as one module, flat Adam moments, SAC's own generator.
constexpr const char* kFormat = "hlt-checkpoint-2";

}  // namespace

struct CheckpointWriter::Impl {
  torch::serialize::OutputArchive root;
  std::map<std::string, std::unique_ptr<torch::serialize::OutputArchive>> nested;
};

CheckpointWriter::CheckpointWriter() : impl_(std::make_unique<Impl>()) {
  impl_->root.write(kFormatKey, c10::IValue(std::string(kFormat)));
}
CheckpointWriter::~CheckpointWriter() = default;

void CheckpointWriter::add_module(const std::string& name, const torch::nn::Module& module) {
  // Flat dotted names ("mean.0.weight"), the same keys load_module looks up.
  auto& out = archive("module." + name);
  for (const auto& item : module.named_parameters(true))
    out.write(item.key(), item.value().detach());
  for (const auto& item : module.named_buffers(true))
    out.write(item.key(), item.value(), /*is_buffer=*/true);
}

void CheckpointWriter::add_optimizer(const std::string& name, const torch::optim::Optimizer& optimizer) {
  optimizer.save(archive("optim." + name));
}

void CheckpointWriter::add_tensor(const std::string& name, const at::Tensor& tensor) {
  impl_->root.write("tensor." + name, tensor);
}

void CheckpointWriter::add_int(const std::string& name, int64_t value) {
  impl_->root.write("int." + name, c10::IValue(value));
}

void CheckpointWriter::add_string(const std::string& name, const std::string& value) {
  impl_->root.write("str." + name, c10::IValue(value));
}

torch::serialize::OutputArchive& CheckpointWriter::archive(const std::string& name) {
  auto& slot = impl_->nested[name];
  if (!slot) slot = std::make_unique<torch::serialize::OutputArchive>();
  return *slot;
}

void CheckpointWriter::save(const std::string& path) {
  for (auto& [name, nested] : impl_->nested)
    impl_->root.write(name, *nested);
  impl_->nested.clear();
  // Serialised in memory, then written with a checksum trailer: LibTorch does not verify its zip records'
  // CRCs, so without it a flipped bit in tensor data would load silently.
  std::string bytes;
  try {
    impl_->root.save_to([&](const void* data, size_t size) {
      bytes.append(static_cast<const char*>(data), size);
      return size;
    });
  } catch (const c10::Error& e) {
    throw Error(fmt::format("cannot write checkpoint {}: {}", path, e.what_without_backtrace()));
  }
  write_file_atomic(path, with_checksum_trailer(std::move(bytes)));
}

struct CheckpointReader::Impl {
  std::string path;
  torch::serialize::InputArchive root;
  std::map<std::string, std::unique_ptr<torch::serialize::InputArchive>> nested;
};

CheckpointReader::CheckpointReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  check(file_exists(path), "checkpoint {} does not exist", path);
  const std::string bytes = read_file(path);
  const std::string_view content = verified_content(bytes, "checkpoint " + path);
  try {
    impl_->root.load_from(content.data(), content.size());
  } catch (const c10::Error& e) {
    throw Error(fmt::format("checkpoint {} is corrupt or not a checkpoint ({})", path,
                            std::string(e.what_without_backtrace()).substr(0, 200)));
  }
  c10::IValue format;
  check(impl_->root.try_read(kFormatKey, format) && format.isString(),
        "{} is not an hlt checkpoint (expected format '{}')", path, kFormat);
  check(format.toStringRef() == kFormat,
        "checkpoint {} has format '{}', this hlt reads '{}' (it was written by another version of hlt: use "
        "that version to resume or run it)",
        path, format.toStringRef(), kFormat);
}
CheckpointReader::~CheckpointReader() = default;

const std::string& CheckpointReader::path() const {
  return impl_->path;
}

bool CheckpointReader::has(const std::string& name) const {
  for (const auto& key : impl_->root.keys()) {
    if (key == name || key == "module." + name || key == "optim." + name || key == "tensor." + name ||
        key == "int." + name || key == "str." + name) {
      return true;
    }
  }
  return false;
}

torch::serialize::InputArchive& CheckpointReader::archive(const std::string& name) {
  auto& slot = impl_->nested[name];
  if (!slot) {
    slot = std::make_unique<torch::serialize::InputArchive>();
    check(impl_->root.try_read(name, *slot), "checkpoint {} has no '{}'", impl_->path, name);
  }
  return *slot;
}

void CheckpointReader::load_module(const std::string& name, torch::nn::Module& module) {
  auto& in = archive("module." + name);
  torch::NoGradGuard no_grad;
  auto load_named = [&](const torch::OrderedDict<std::string, torch::Tensor>& named, bool is_buffer) {
    for (const auto& item : named) {
      torch::Tensor stored;
      check(in.try_read(item.key(), stored, is_buffer), "checkpoint {}: '{}' has no parameter '{}'",
            impl_->path, name, item.key());
      check(stored.sizes() == item.value().sizes(),
            "checkpoint {}: '{}.{}' has shape {}, the model expects {}", impl_->path, name, item.key(),
            fmt::join(stored.sizes(), "x"), fmt::join(item.value().sizes(), "x"));
      check(stored.dtype() == item.value().dtype(),
            "checkpoint {}: '{}.{}' has dtype {}, the model expects {}", impl_->path, name, item.key(),
            std::string(stored.dtype().name()), std::string(item.value().dtype().name()));
      item.value().copy_(stored);
    }
  };
  load_named(module.named_parameters(true), false);
  load_named(module.named_buffers(true), true);
}

void CheckpointReader::load_optimizer(const std::string& name, torch::optim::Optimizer& optimizer) {
  try {
    optimizer.load(archive("optim." + name));
  } catch (const c10::Error& e) {
    throw Error(fmt::format("checkpoint {}: optimizer '{}' does not match ({})", impl_->path, name,
                            std::string(e.what_without_backtrace()).substr(0, 200)));
  }
}

at::Tensor CheckpointReader::tensor(const std::string& name) {
  torch::Tensor t;
  check(impl_->root.try_read("tensor." + name, t), "checkpoint {} has no tensor '{}'", impl_->path, name);
  return t;
}

int64_t CheckpointReader::get_int(const std::string& name) {
  c10::IValue v;
  check(impl_->root.try_read("int." + name, v) && v.isInt(), "checkpoint {} has no integer '{}'", impl_->path,
        name);
  return v.toInt();
}

std::string CheckpointReader::get_string(const std::string& name) {
  c10::IValue v;
  check(impl_->root.try_read("str." + name, v) && v.isString(), "checkpoint {} has no string '{}'",
        impl_->path, name);
  return v.toStringRef();
}

}  // namespace hlt
