#pragma once
// Content hashes for provenance and integrity: XXH3-128 (xxHash), printed as 32 hex digits.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace linebake {

class Hasher {
 public:
  Hasher();
  ~Hasher();
  Hasher(const Hasher&) = delete;
  Hasher& operator=(const Hasher&) = delete;
  Hasher& update(const void* data, size_t bytes);
  Hasher& update(std::string_view text);  // length-prefixed, so "ab"+"c" != "a"+"bc"
  Hasher& update(uint64_t value);
  std::string hex() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

std::string hash_bytes(const void* data, size_t bytes);
// Hash of a file's bytes; throws InputError if it cannot be read.
std::string hash_file(const std::string& path);

}  // namespace linebake
