#include "agents/demonstrations.h"

#include <cmath>
#include <cstring>
#include <sstream>

#include "hlt/util/checksum.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

int64_t row_size(int n, int m) {
  return 3 + 2 * static_cast<int64_t>(n) + m + 2;
}

bool finite(const Eigen::VectorXd& v) {
  return v.allFinite();
}

}  // namespace

Demonstrations::Demonstrations(std::string env, int observation_dim, int action_dim, int frame_skip,
                               std::string source)
    : env_(std::move(env)),
      n_(observation_dim),
      m_(action_dim),
      frame_skip_(frame_skip),
      source_(std::move(source)) {
  check(!env_.empty() && env_.find_first_of(" \n") == std::string::npos, "demonstrations need an env name");
  check(n_ > 0 && m_ > 0 && frame_skip_ > 0, "demonstrations need positive sizes and frame skip");
  for (char& c : source_)
    if (c == '\n') c = ' ';
}

void Demonstrations::add_episode(std::vector<DemoStep> steps) {
  check(!steps.empty(), "a demonstration episode needs at least one step");
  for (const DemoStep& s : steps) {
    check(s.observation.size() == n_ && s.next_observation.size() == n_ && s.action.size() == m_,
          "a demonstration step has sizes {}/{}/{}, expected {}/{}/{}", s.observation.size(), s.action.size(),
          s.next_observation.size(), n_, m_, n_);
    check(finite(s.observation) && finite(s.action) && finite(s.next_observation) && std::isfinite(s.reward),
          "a demonstration step holds a non-finite number");
  }
  episodes_.push_back(std::move(steps));
}

int64_t Demonstrations::transitions() const {
  int64_t t = 0;
  for (const auto& e : episodes_)
    t += static_cast<int64_t>(e.size());
  return t;
}

void Demonstrations::save(const std::string& path) const {
  std::string out = fmt::format(
      "{} {}\nenv {}\nobservation_dim {}\naction_dim {}\nframe_skip {}\nsource {}\nepisodes {}\ntransitions "
      "{}\ndata\n",
      kMagic, kVersion, env_, n_, m_, frame_skip_, source_, episodes_.size(), transitions());
  std::vector<double> row(static_cast<size_t>(row_size(n_, m_)));
  for (size_t e = 0; e < episodes_.size(); ++e) {
    for (size_t t = 0; t < episodes_[e].size(); ++t) {
      const DemoStep& s = episodes_[e][t];
      size_t k = 0;
      row[k++] = static_cast<double>(e);
      row[k++] = static_cast<double>(t);
      for (int i = 0; i < n_; ++i)
        row[k++] = s.observation[i];
      for (int i = 0; i < m_; ++i)
        row[k++] = s.action[i];
      row[k++] = s.reward;
      for (int i = 0; i < n_; ++i)
        row[k++] = s.next_observation[i];
      row[k++] = s.terminated ? 1 : 0;
      row[k++] = s.truncated ? 1 : 0;
      out.append(reinterpret_cast<const char*>(row.data()), row.size() * sizeof(double));
    }
  }
  write_file_atomic(path, with_checksum_trailer(std::move(out)));
}

Demonstrations Demonstrations::load(const std::string& path) {
  const std::string bytes = read_file(path);
  const std::string_view content = verified_content(bytes, "demonstrations " + path);
  size_t pos = 0;
  auto line = [&](const char* key) {
    const size_t eol = content.find('\n', pos);
    check(eol != std::string_view::npos, "{}: the header ends early (no '{}' line)", path, key);
    std::string l(content.substr(pos, eol - pos));
    pos = eol + 1;
    const std::string prefix = std::string(key) + " ";
    check(l.rfind(prefix, 0) == 0 || (l == key && std::string(key) == "data"),
          "{}: expected a '{}' line, got '{}'", path, key, l.substr(0, 80));
    return l.size() > prefix.size() ? l.substr(prefix.size()) : std::string();
  };
  auto number = [&](const char* key) {
    const std::string v = line(key);
    char* end = nullptr;
    const long long x = std::strtoll(v.c_str(), &end, 10);
    check(end != v.c_str() && *end == '\0' && x >= 0, "{}: '{}' must be a non-negative integer, got '{}'",
          path, key, v);
    return static_cast<int64_t>(x);
  };
  const int64_t version = number(kMagic);
  check(version == kVersion, "{}: demonstrations format version {}, this hlt reads version {}", path, version,
        kVersion);
  const std::string env = line("env");
  const int64_t n = number("observation_dim"), m = number("action_dim"), k = number("frame_skip");
  const std::string source = line("source");
  const int64_t episodes = number("episodes"), transitions = number("transitions");
  line("data");
  check(n > 0 && m > 0 && k > 0 && n < 100000 && m < 100000, "{}: implausible sizes in the header", path);
  const int64_t row = row_size(static_cast<int>(n), static_cast<int>(m));
  const size_t expected = static_cast<size_t>(transitions * row) * sizeof(double);
  check(content.size() - pos == expected,
        "{}: the header promises {} transitions ({} bytes), the file holds {}", path, transitions, expected,
        content.size() - pos);
  Demonstrations d(env, static_cast<int>(n), static_cast<int>(m), static_cast<int>(k), source);
  std::vector<double> r(static_cast<size_t>(row));
  std::vector<DemoStep> current;
  int64_t episode = 0;
  for (int64_t t = 0; t < transitions; ++t) {
    std::memcpy(r.data(), content.data() + pos + static_cast<size_t>(t * row) * sizeof(double),
                r.size() * sizeof(double));
    if (r[0] != static_cast<double>(episode)) {
      check(r[0] == static_cast<double>(episode + 1) && !current.empty(),
            "{}: transition {} belongs to episode {}, expected {} or {}", path, t, r[0], episode,
            episode + 1);
      d.add_episode(std::move(current));
      current.clear();
      ++episode;
    }
    check(r[1] == static_cast<double>(current.size()),
          "{}: transition {} is step {} of its episode, expected {}", path, t, r[1], current.size());
    DemoStep s;
    size_t i = 2;
    s.observation = Eigen::Map<const Eigen::VectorXd>(r.data() + i, n);
    i += n;
    s.action = Eigen::Map<const Eigen::VectorXd>(r.data() + i, m);
    i += m;
    s.reward = r[i++];
    s.next_observation = Eigen::Map<const Eigen::VectorXd>(r.data() + i, n);
    i += n;
    s.terminated = r[i++] != 0;
    s.truncated = r[i++] != 0;
    current.push_back(std::move(s));
  }
  if (!current.empty()) d.add_episode(std::move(current));
  check(static_cast<int64_t>(d.episodes().size()) == episodes,
        "{}: the header promises {} episodes, the data holds {}", path, episodes, d.episodes().size());
  return d;
}

void Demonstrations::check_matches(const std::string& env, int observation_dim, int action_dim,
                                   int frame_skip) const {
  check(env == env_ && observation_dim == n_ && action_dim == m_ && frame_skip == frame_skip_,
        "the demonstrations were recorded on {} (observation {}, action {}, frame skip {}), not on {} "
        "(observation {}, action {}, frame skip {})",
        env_, n_, m_, frame_skip_, env, observation_dim, action_dim, frame_skip);
}

}  // namespace hlt
