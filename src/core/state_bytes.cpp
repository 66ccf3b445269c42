#include "arthrosim/core/state_bytes.h"

#include <array>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "arthrosim/core/hash.h"
#include "arthrosim/core/state_fields.h"

namespace arthrosim {
namespace {

template <class T>
concept HasFields = requires(const T& t) {
  VisitFields(t, [](const auto&, const FieldInfo&) {});
};

template <class T>
concept EigenDense = requires(const T& t) {
  t.rows();
  t.cols();
  t.data();
};

/// The elements of *r that v's are coded against: all of r's when it has v's row count, else
/// none.
template <class T>
std::pair<const typename T::Scalar*, std::size_t> ReferenceElements(const T& v, const T* r) {
  if (r == nullptr || r->rows() != v.rows()) return {nullptr, 0};
  return {r->data(), static_cast<std::size_t>(r->size())};
}

/// Calls f(member, ref) for every member of v in table order; ref points to the same member of
/// *r (nullptr when r is null).
template <class T, class F>
void ForEachMemberWithRef(T& v, const std::remove_const_t<T>* r, F&& f) {
  std::array<const void*, kMaxStateFields> refs{};
  const std::size_t n_ref = FieldAddresses(r, &refs);
  std::size_t i = 0;
  VisitFields(v, [&](auto& member, const FieldInfo&) {
    using M = std::decay_t<decltype(member)>;
    f(member, i < n_ref ? static_cast<const M*>(refs[i]) : nullptr);
    ++i;
  });
}

/// Writes `n` elements of `element` bytes XORed with the first `n_ref` elements of `ref`; in byte
/// planes when `planes` (doubles).
void PutXor(const std::uint8_t* p, const std::uint8_t* ref, std::size_t n, std::size_t n_ref,
            std::size_t element, bool planes, std::vector<std::uint8_t>* out) {
  const std::size_t at = out->size();
  out->resize(at + n * element);
  std::uint8_t* o = out->data() + at;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t b = 0; b < element; ++b) {
      const std::uint8_t r = i < n_ref ? ref[i * element + b] : 0;
      o[planes ? b * n + i : i * element + b] = static_cast<std::uint8_t>(p[i * element + b] ^ r);
    }
  }
}

class Encoder {
 public:
  explicit Encoder(std::vector<std::uint8_t>* out) : out_(out) {}

  template <class T>
  void Field(const T& v, const T* r) {
    if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
      Raw(&v, sizeof(T));
    } else if constexpr (std::is_same_v<T, std::string>) {
      Count(v.size());
      Raw(v.data(), v.size());
    } else if constexpr (std::is_same_v<T, Pose>) {
      Field(v.position_mm, r != nullptr ? &r->position_mm : nullptr);
      Field(v.orientation.coeffs(), r != nullptr ? &r->orientation.coeffs() : nullptr);
    } else if constexpr (EigenDense<T>) {
      const std::int64_t shape[2] = {v.rows(), v.cols()};
      Raw(shape, sizeof shape);
      const auto [ref, n_ref] = ReferenceElements(v, r);
      Elements(v.data(), static_cast<std::size_t>(v.size()), ref, n_ref);
    } else if constexpr (HasFields<T>) {
      ForEachMemberWithRef(v, r, [&](auto& member, const auto* ref) { Field(member, ref); });
    } else if constexpr (HasFields<typename T::value_type>) {  // list of records
      Count(v.size());
      for (std::size_t i = 0; i < v.size(); ++i) {
        Field(v[i], r != nullptr && i < r->size() ? &(*r)[i] : nullptr);
      }
    } else {  // vector / array of trivially copyable elements
      static_assert(std::is_trivially_copyable_v<typename T::value_type>);
      Count(v.size());
      Elements(v.data(), v.size(), r != nullptr ? r->data() : nullptr,
               r != nullptr ? r->size() : 0);
    }
  }

 private:
  void Raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    out_->insert(out_->end(), c, c + n);
  }
  void Count(std::size_t n) {
    const std::uint64_t c = n;
    Raw(&c, sizeof c);
  }
  template <class E>
  void Elements(const E* p, std::size_t n, const E* ref, std::size_t n_ref) {
    PutXor(reinterpret_cast<const std::uint8_t*>(p), reinterpret_cast<const std::uint8_t*>(ref), n,
           ref != nullptr ? n_ref : 0, sizeof(E), std::is_same_v<E, double>, out_);
  }
  std::vector<std::uint8_t>* out_;
};

class Decoder {
 public:
  explicit Decoder(std::span<const std::uint8_t> in) : in_(in) {}

  template <class T>
  void Field(T& v, const T* r) {
    if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
      Raw(&v, sizeof(T));
    } else if constexpr (std::is_same_v<T, std::string>) {
      v.resize(Count(1));
      Raw(v.data(), v.size());
    } else if constexpr (std::is_same_v<T, Pose>) {
      Field(v.position_mm, r != nullptr ? &r->position_mm : nullptr);
      Field(v.orientation.coeffs(), r != nullptr ? &r->orientation.coeffs() : nullptr);
    } else if constexpr (EigenDense<T>) {
      std::int64_t shape[2] = {0, 0};
      Raw(shape, sizeof shape);
      constexpr int kRows = T::RowsAtCompileTime, kCols = T::ColsAtCompileTime;
      if (shape[0] < 0 || shape[1] < 0 || (kRows >= 0 && shape[0] != kRows) ||
          (kCols >= 0 && shape[1] != kCols) ||
          static_cast<std::uint64_t>(shape[0]) * static_cast<std::uint64_t>(shape[1]) >
              Left() / sizeof(double)) {
        Fail("a matrix shape that does not fit this build's State");
      }
      v.resize(shape[0], shape[1]);
      const auto [ref, n_ref] = ReferenceElements(v, r);
      Elements(v.data(), static_cast<std::size_t>(v.size()), ref, n_ref);
    } else if constexpr (HasFields<T>) {
      ForEachMemberWithRef(v, r, [&](auto& member, const auto* ref) { Field(member, ref); });
    } else if constexpr (HasFields<typename T::value_type>) {  // list of records
      const std::size_t n = Count(1);
      Resize(v, n);
      for (std::size_t i = 0; i < n; ++i) {
        Field(v[i], r != nullptr && i < r->size() ? &(*r)[i] : nullptr);
      }
    } else {
      using E = typename T::value_type;
      const std::size_t n = Count(sizeof(E));
      Resize(v, n);
      Elements(v.data(), n, r != nullptr ? r->data() : nullptr, r != nullptr ? r->size() : 0);
    }
  }

  void Finish() const {
    if (at_ != in_.size()) Fail("trailing bytes after the State");
  }

 private:
  [[noreturn]] static void Fail(const std::string& what) {
    throw std::runtime_error("checkpoint: " + what);
  }
  std::size_t Left() const { return in_.size() - at_; }
  void Raw(void* p, std::size_t n) {
    if (n > Left()) Fail("truncated");
    if (n > 0) std::memcpy(p, in_.data() + at_, n);
    at_ += n;
  }
  /// A count of elements of at least `element` bytes each, checked against the bytes left.
  std::size_t Count(std::size_t element) {
    std::uint64_t c = 0;
    Raw(&c, sizeof c);
    if (c > Left() / element) Fail("a count larger than the bytes that follow");
    return static_cast<std::size_t>(c);
  }
  template <class T>
  static void Resize(T& v, std::size_t n) {
    if constexpr (requires { v.resize(n); }) {
      v.resize(n);
    } else if (n != v.size()) {  // std::array
      Fail("a fixed-size list of another length (a file from another build)");
    }
  }
  template <class E>
  void Elements(E* p, std::size_t n, const E* ref, std::size_t n_ref) {
    const std::size_t element = sizeof(E);
    if (n > Left() / element) Fail("truncated");
    const bool planes = std::is_same_v<E, double>;
    auto* o = reinterpret_cast<std::uint8_t*>(p);
    const auto* r = reinterpret_cast<const std::uint8_t*>(ref);
    const std::uint8_t* in = in_.data() + at_;
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t b = 0; b < element; ++b) {
        const std::uint8_t x = r != nullptr && i < n_ref ? r[i * element + b] : 0;
        o[i * element + b] =
            static_cast<std::uint8_t>(in[planes ? b * n + i : i * element + b] ^ x);
      }
    }
    at_ += n * element;
  }

  std::span<const std::uint8_t> in_;
  std::size_t at_ = 0;
};

template <class T>
void Signature(Fnv1a* h) {
  if constexpr (HasFields<T>) {
    T sample{};
    VisitFields(sample, [&](const auto& member, const FieldInfo& info) {
      h->Add(info.name, std::strlen(info.name));
      h->AddValue(info.store);
      Signature<std::decay_t<decltype(member)>>(h);
    });
  } else if constexpr (requires { typename T::value_type; } && !std::is_same_v<T, std::string> &&
                       !EigenDense<T>) {
    h->AddValue(std::uint8_t{1});
    Signature<typename T::value_type>(h);
  } else {
    h->AddValue(static_cast<std::uint64_t>(sizeof(T)));
  }
}

}  // namespace

void EncodeState(const State& s, const State& reference, std::vector<std::uint8_t>* out) {
  out->clear();
  Encoder(out).Field(s, &reference);
}

void DecodeState(std::span<const std::uint8_t> bytes, const State& reference, State* out) {
  Decoder d(bytes);
  d.Field(*out, &reference);
  d.Finish();
}

std::uint64_t StateLayoutSignature() {
  Fnv1a h;
  Signature<State>(&h);
  return h.digest();
}

}  // namespace arthrosim
