#include "agents/expert_policy.h"

#include <cmath>
#include <sstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

struct Array {
  std::string name;
  Eigen::MatrixXd values;
};

// Reads "NAME ROWS COLS" and ROWS lines of COLS numbers, counting lines for the messages.
bool read_array(std::istringstream& in, int& line_no, const std::string& path, Array& out) {
  std::string line;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") != std::string::npos) break;
    line.clear();
  }
  if (line.empty()) return false;
  std::istringstream header(line);
  long rows = 0, cols = 0;
  std::string rest;
  check(static_cast<bool>(header >> out.name >> rows >> cols) && !(header >> rest) && rows > 0 && cols > 0 &&
            rows <= 100000 && cols <= 100000,
        "{}:{}: expected a header 'NAME ROWS COLS', got '{}'", path, line_no, line.substr(0, 80));
  out.values.resize(rows, cols);
  for (long r = 0; r < rows; ++r) {
    check(static_cast<bool>(std::getline(in, line)), "{}: '{}' is truncated: {} of its {} rows are missing",
          path, out.name, rows - r, rows);
    ++line_no;
    std::istringstream row(line);
    for (long c = 0; c < cols; ++c) {
      std::string word;
      check(static_cast<bool>(row >> word), "{}:{}: '{}' row {} has {} numbers, expected {}", path, line_no,
            out.name, r, c, cols);
      char* end = nullptr;
      const double x = std::strtod(word.c_str(), &end);
      check(end != word.c_str() && *end == '\0' && std::isfinite(x), "{}:{}: '{}' is not a finite number",
            path, line_no, word);
      out.values(r, c) = x;
    }
    std::string extra;
    check(!(row >> extra), "{}:{}: '{}' row {} has more than {} numbers", path, line_no, out.name, r, cols);
  }
  return true;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

ExpertPolicy::ExpertPolicy(const std::string& path) : path_(path) {
  std::istringstream in(read_file(path));
  int line_no = 0;
  std::vector<Array> arrays;
  for (Array a; read_array(in, line_no, path, a); a = Array{})
    arrays.push_back(std::move(a));
  check(!arrays.empty() && arrays.size() % 2 == 0,
        "{}: expected pairs of arrays (NAME_w, then NAME_b), found {} arrays", path, arrays.size());
  for (size_t i = 0; i < arrays.size(); i += 2) {
    const Array &w = arrays[i], &b = arrays[i + 1];
    check(ends_with(w.name, "_w") && ends_with(b.name, "_b") &&
              w.name.substr(0, w.name.size() - 2) == b.name.substr(0, b.name.size() - 2),
          "{}: layer {} must be 'NAME_w' then 'NAME_b', got '{}' and '{}'", path, i / 2, w.name, b.name);
    check(b.values.rows() == 1 && b.values.cols() == w.values.cols(),
          "{}: '{}' is {}x{}, expected 1x{} for '{}'", path, b.name, b.values.rows(), b.values.cols(),
          w.values.cols(), w.name);
    if (!weights_.empty())
      check(w.values.rows() == weights_.back().cols(), "{}: '{}' has {} rows, the layer before gives {}",
            path, w.name, w.values.rows(), weights_.back().cols());
    weights_.push_back(w.values);
    biases_.push_back(b.values.row(0));
  }
}

std::string ExpertPolicy::describe() const {
  std::string sizes = std::to_string(observation_dim());
  for (const auto& w : weights_)
    sizes += "x" + std::to_string(w.cols());
  return "expert " + path_ + " (ReLU MLP " + sizes + ")";
}

Eigen::VectorXd ExpertPolicy::act(const Eigen::VectorXd& observation) {
  check(observation.size() == observation_dim(), "{}: observation has {} numbers, the expert expects {}",
        path_, observation.size(), observation_dim());
  Eigen::RowVectorXd x = observation.transpose();
  for (size_t l = 0; l < weights_.size(); ++l) {
    x = x * weights_[l] + biases_[l];
    if (l + 1 < weights_.size()) x = x.cwiseMax(0.0);
  }
  return x.transpose().cwiseMax(-1.0).cwiseMin(1.0);
}

}  // namespace hlt
