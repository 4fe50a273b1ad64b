#include "core/hash.hpp"

#include <xxhash.h>

#include <cstdio>
#include <fstream>
#include <vector>

#include "core/error.hpp"

namespace linebake {

struct Hasher::State {
  XXH3_state_t* state = XXH3_createState();
  ~State() { XXH3_freeState(state); }
};

Hasher::Hasher() : state_(std::make_unique<State>()) {
  XXH3_128bits_reset(state_->state);
}
Hasher::~Hasher() = default;

Hasher& Hasher::update(const void* data, size_t bytes) {
  XXH3_128bits_update(state_->state, data, bytes);
  return *this;
}

Hasher& Hasher::update(std::string_view text) {
  update(uint64_t{text.size()});
  return update(text.data(), text.size());
}

Hasher& Hasher::update(uint64_t value) {
  return update(&value, sizeof value);
}

static std::string to_hex(XXH128_hash_t h) {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(h.high64),
                static_cast<unsigned long long>(h.low64));
  return text;
}

std::string Hasher::hex() const {
  return to_hex(XXH3_128bits_digest(state_->state));
}

std::string hash_bytes(const void* data, size_t bytes) {
  return to_hex(XXH3_128bits(data, bytes));
}

std::string hash_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open");
  Hasher hasher;
  std::vector<char> buffer(size_t{1} << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    hasher.update(buffer.data(), static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) throw InputError(path, "", "read error");
  return hasher.hex();
}

}  // namespace linebake
