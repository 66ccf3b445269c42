#pragma once
// A State as bytes, exact: the checkpoint encoding of the run file (docs/hdf5-layout.md,
// "Checkpoints"). Walks the State field table (core/state_fields.h), so a new State field is
// checkpointed by adding its line there. Every field is kept, derived ones included (a restored
// State equals the saved one bit for bit, BoneState::revision too).
//
// Encoding, field by field in table order (native little-endian):
//   number / enum       its bytes
//   string              uint64 length, bytes
//   Eigen matrix        int64 rows, int64 cols, then the doubles (column-major)
//   vector / array      uint64 count, then the elements (records field by field)
// The doubles and other element bytes of a field are XORed with the same field of a reference
// State (the Model's initial state: rest positions, initial tets and surfaces, zero velocities)
// over the elements both have, and the bytes of doubles are stored in byte planes (all first
// bytes, then all second bytes...). What did not change since t = 0 then becomes runs of zeros
// and positions near rest share their sign, exponent and high mantissa bytes, which deflate
// removes. Decoding needs the same reference.
#include <cstdint>
#include <span>
#include <vector>

#include "arthrosim/core/state.h"

namespace arthrosim {

/// Appends the encoding of `s` relative to `reference` to *out (*out is cleared first; its
/// capacity is reused).
void EncodeState(const State& s, const State& reference, std::vector<std::uint8_t>* out);

/// Decodes bytes written by EncodeState with the same reference into *out.
/// @throws std::runtime_error if the bytes are truncated, have trailing bytes or a count that
///         does not fit the State's layout (a file written by another build).
void DecodeState(std::span<const std::uint8_t> bytes, const State& reference, State* out);

/// A 64-bit signature of the State's layout: every field's name, store and C++ size, recursively
/// through the field table. Two builds with equal signatures encode States the same way.
std::uint64_t StateLayoutSignature();

}  // namespace arthrosim
