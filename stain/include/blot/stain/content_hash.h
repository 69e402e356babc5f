#pragma once
/// The one content hash (64-bit FNV-1a over raw bytes) for state hashes, mesh
/// fingerprints and cache keys. Not cryptographic; identical bytes give
/// identical hashes on the same platform.
#include <cstddef>
#include <cstdint>

namespace blot::stain {

inline constexpr std::uint64_t kContentHashBasis = 14695981039346656037ull;  ///< FNV-1a offset basis

/// Folds `bytes` bytes at `data` into `hash` (start from kContentHashBasis).
inline void hashBytes(std::uint64_t& hash, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;  // FNV-1a 64-bit prime
  }
}

/// Folds a dense array's coefficients (its storage order, no shape) into `hash`.
template <typename Array>
void hashArray(std::uint64_t& hash, const Array& a) {
  const auto& m = a.derived();
  hashBytes(hash, m.data(), sizeof(typename Array::Scalar) * static_cast<std::size_t>(m.size()));
}

}  // namespace blot::stain
