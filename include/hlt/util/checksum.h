// A 64-bit checksum for detecting corrupted files (bit flips, truncation, partial writes), and the trailer
// that carries it: files that must not load silently when damaged (checkpoints) end with
// "HLTSUM01" followed by the checksum of everything before the trailer, little-endian.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace hlt {

// Not cryptographic: a fast multiply-rotate hash over 8-byte words (any single bit flip changes it).
uint64_t checksum64(const char* data, size_t size);

// `content` with its trailer appended.
std::string with_checksum_trailer(std::string content);

// The content without its trailer; throws hlt::Error naming `source` if the trailer is missing or the
// checksum does not match.
std::string_view verified_content(const std::string& bytes, const std::string& source);

}  // namespace hlt
