#pragma once
// The one RAII owner of an HDF5 id, shared by the run files (io) and recorded sessions (input).
// In the core layer because input and io are siblings; header-only, so only the libraries that
// use it need HDF5 (they link it themselves).
#include <hdf5.h>

#include <utility>

namespace arthrosim::h5 {

/// Owns one hid_t and closes it with the right H5*close on destruction. Move-only.
class Handle {
 public:
  Handle() = default;
  /// Takes id (closed by close); an id < 0 (a failed HDF5 call) is held as invalid.
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept { *this = std::move(o); }
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      Reset();
      id_ = o.id_;
      close_ = o.close_;
      o.id_ = -1;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { Reset(); }

  /// Closes the id now (errors ignored: destructors must not throw).
  void Reset() noexcept {
    if (id_ >= 0 && close_ != nullptr && H5Iis_valid(id_) > 0) close_(id_);
    id_ = -1;
  }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

}  // namespace arthrosim::h5
