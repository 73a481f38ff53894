#include "hlt/util/checksum.h"

#include <cstring>

#include "hlt/util/error.h"

namespace hlt {
namespace {

constexpr char kMagic[8] = {'H', 'L', 'T', 'S', 'U', 'M', '0', '1'};
constexpr size_t kTrailer = 16;

uint64_t rotl(uint64_t x, int r) {
  return (x << r) | (x >> (64 - r));
}

}  // namespace

uint64_t checksum64(const char* data, size_t size) {
  constexpr uint64_t k1 = 0x9E3779B185EBCA87ULL, k2 = 0xC2B2AE3D27D4EB4FULL;
  uint64_t h = 0x27D4EB2F165667C5ULL ^ (size * k1);
  size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    std::memcpy(&w, data + i, 8);
    h = rotl(h ^ (rotl(w * k2, 31) * k1), 27) * k1 + k2;
  }
  uint64_t tail = 0;
  std::memcpy(&tail, data + i, size - i);
  h = rotl(h ^ (rotl(tail * k2, 31) * k1), 27) * k1 + k2;
  h ^= h >> 33;
  h *= k2;
  h ^= h >> 29;
  return h;
}

std::string with_checksum_trailer(std::string content) {
  const uint64_t sum = checksum64(content.data(), content.size());
  content.append(kMagic, sizeof kMagic);
  for (int b = 0; b < 8; ++b)
    content.push_back(static_cast<char>((sum >> (8 * b)) & 0xFF));
  return content;
}

std::string_view verified_content(const std::string& bytes, const std::string& source) {
  check(bytes.size() >= kTrailer && std::memcmp(bytes.data() + bytes.size() - kTrailer, kMagic, 8) == 0,
        "{} is truncated or corrupt (its checksum trailer is missing), or was not written by this version of "
        "hlt",
        source);
  uint64_t stored = 0;
  for (int b = 0; b < 8; ++b)
    stored |= static_cast<uint64_t>(static_cast<unsigned char>(bytes[bytes.size() - 8 + b])) << (8 * b);
  const size_t n = bytes.size() - kTrailer;
  check(checksum64(bytes.data(), n) == stored, "{} is corrupt: its checksum does not match its content",
        source);
  return std::string_view(bytes.data(), n);
}

}  // namespace hlt
