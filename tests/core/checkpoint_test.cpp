#include "hlt/core/checkpoint.h"
#include "hlt/util/checksum.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <filesystem>
#include <fstream>

#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "support/error_of.h"

namespace hlt {
namespace {

std::string temp(const std::string& name) {
  return (std::filesystem::temp_directory_path() / name).string();
}

using testing::error_of;

TEST(Checkpoint, ModulesOptimizersAndValuesRoundTrip) {
  torch::manual_seed(0);
  GaussianPolicy policy(GaussianPolicyOptions{3, 2, {16}, Activation::kSin});
  torch::optim::Adam opt(policy->parameters(), torch::optim::AdamOptions(1e-3));
  // Take a step so the optimizer has state worth saving.
  auto s = torch::randn({8, 3});
  policy->log_prob(s, torch::zeros({8, 2})).sum().neg().backward();
  opt.step();
  const std::string path = temp("hlt_ckpt_test.pt");
  {
    CheckpointWriter w;
    w.add_module("policy", *policy);
    w.add_optimizer("policy", opt);
    w.add_int("step", 1234);
    w.add_string("env", "pendulum");
    w.add_tensor("log_alpha", torch::tensor({-0.5}));
    w.save(path);
  }
  GaussianPolicy other(GaussianPolicyOptions{3, 2, {16}, Activation::kSin});
  torch::optim::Adam other_opt(other->parameters(), torch::optim::AdamOptions(1e-3));
  CheckpointReader r(path);
  r.load_module("policy", *other);
  r.load_optimizer("policy", other_opt);
  EXPECT_EQ(r.get_int("step"), 1234);
  EXPECT_EQ(r.get_string("env"), "pendulum");
  EXPECT_FLOAT_EQ(r.tensor("log_alpha").item<float>(), -0.5f);
  EXPECT_TRUE(r.has("policy"));
  EXPECT_FALSE(r.has("critic"));
  for (size_t i = 0; i < policy->parameters().size(); ++i) {
    EXPECT_TRUE(torch::equal(policy->parameters()[i], other->parameters()[i]));
  }
  // Both optimizers take the same next step from the same state.
  opt.zero_grad();
  other_opt.zero_grad();
  policy->log_prob(s, torch::zeros({8, 2})).sum().neg().backward();
  other->log_prob(s, torch::zeros({8, 2})).sum().neg().backward();
  opt.step();
  other_opt.step();
  for (size_t i = 0; i < policy->parameters().size(); ++i) {
    EXPECT_TRUE(torch::allclose(policy->parameters()[i], other->parameters()[i]));
  }
}

TEST(Checkpoint, MismatchedModelIsNamed) {
  const std::string path = temp("hlt_ckpt_mismatch.pt");
  DynamicsModel small(DynamicsModelOptions{3, 1, 20});
  CheckpointWriter w;
  w.add_module("dynamics", *small);
  w.save(path);
  DynamicsModel big(DynamicsModelOptions{3, 1, 200});
  CheckpointReader r(path);
  const std::string m = error_of([&] { r.load_module("dynamics", *big); });
  EXPECT_NE(m.find("dynamics.fc1.weight' has shape 20x4, the model expects 200x4"), std::string::npos) << m;
  EXPECT_NE(error_of([&] { r.load_module("policy", *big); }).find("has no 'module.policy'"),
            std::string::npos);
  EXPECT_NE(error_of([&] { r.get_int("step"); }).find("no integer 'step'"), std::string::npos);
}

TEST(Checkpoint, TruncatedCorruptAndMissingFilesAreClearErrors) {
  const std::string path = temp("hlt_ckpt_trunc.pt");
  DynamicsModel model(DynamicsModelOptions{5, 2, 200});
  CheckpointWriter w;
  w.add_module("dynamics", *model);
  w.save(path);
  const std::string full = read_file(path);
  write_file_atomic(path, full.substr(0, full.size() / 2));
  std::string m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("is truncated or corrupt (its checksum trailer is missing)"), std::string::npos) << m;
  write_file_atomic(path, "this is not a zip file");
  m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("checksum trailer is missing"), std::string::npos) << m;
  m = error_of([&] { CheckpointReader r(temp("hlt_no_such_checkpoint.pt")); });
  EXPECT_NE(m.find("does not exist"), std::string::npos) << m;
  // One flipped bit inside the tensor data (LibTorch itself would load it).
  std::string flipped = full;
  flipped[flipped.size() / 2] ^= 0x10;
  write_file_atomic(path, flipped);
  m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("is corrupt: its checksum does not match"), std::string::npos) << m;
  // A valid torch archive that is not ours, with and without a trailer.
  torch::serialize::OutputArchive foreign;
  foreign.write("x", torch::ones({2}));
  foreign.save_to(path);
  m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("checksum trailer is missing"), std::string::npos) << m;
  write_file_atomic(path, with_checksum_trailer(read_file(path)));
  m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("not an hlt checkpoint"), std::string::npos) << m;
  // Garbage with a valid trailer is still refused as corrupt.
  write_file_atomic(path, with_checksum_trailer("this is not a zip file"));
  m = error_of([&] { CheckpointReader r(path); });
  EXPECT_NE(m.find("is corrupt or not a checkpoint"), std::string::npos) << m;
}

TEST(Checkpoint, SaveIsAtomic) {
  // A failing writer leaves the previous checkpoint untouched and no temporary file behind.
  const std::string path = temp("hlt_ckpt_atomic.pt");
  write_file_atomic(path, "previous");
  EXPECT_THROW(write_atomic_with(path, [](const std::string&) { throw Error("disk full"); }), Error);
  EXPECT_EQ(read_file(path), "previous");
  for (auto& e : std::filesystem::directory_iterator(std::filesystem::temp_directory_path())) {
    EXPECT_EQ(e.path().filename().string().find("hlt_ckpt_atomic.pt.tmp"), std::string::npos);
  }
}

}  // namespace
}  // namespace hlt
