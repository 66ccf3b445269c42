#pragma once
// Small hashing utilities: FNV-1a for state fingerprints, SHA-256 for scenario identity.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace arthrosim {

/// Incremental 64-bit FNV-1a over raw bytes (bit patterns, so -0.0 != 0.0).
class Fnv1a {
 public:
  void Add(const void* data, std::size_t bytes);
  template <class T>
  void AddValue(const T& v) {
    Add(&v, sizeof(T));
  }
  std::uint64_t digest() const { return h_; }

 private:
  std::uint64_t h_ = 1469598103934665603ull;
};

/// SHA-256 of a byte string as 64 lower-case hex characters (FIPS 180-4).
std::string Sha256Hex(std::string_view data);

}  // namespace arthrosim
