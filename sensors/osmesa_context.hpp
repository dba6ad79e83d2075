#pragma once
// An off-screen OpenGL context from Mesa's software renderer: works headless, without X or a GPU.

#include <vector>

// OSMesa's opaque context type, so that this header does not pull in the GL headers
struct osmesa_context;

namespace conesim::sensors {

/// One OSMesa context (RGBA, 24-bit depth, 8-bit stencil) with its own default framebuffer.
/// A context is current on one thread at a time: call make_current() before any GL or mjr_ call.
class OsMesaContext {
 public:
  /// Creates the context and a width x height default framebuffer, and makes it current.
  /// Throws std::runtime_error when OSMesa cannot create or bind the context.
  OsMesaContext(int width_px, int height_px);
  ~OsMesaContext();
  OsMesaContext(const OsMesaContext&) = delete;
  OsMesaContext& operator=(const OsMesaContext&) = delete;

  /// Makes this context current on the calling thread; throws std::runtime_error on failure.
  void make_current();
  /// Makes this context current on the calling thread; false on failure.
  bool try_make_current() noexcept;

 private:
  osmesa_context* context_ = nullptr;
  std::vector<unsigned char> buffer_;
  int width_px_ = 0;
  int height_px_ = 0;
};

}  // namespace conesim::sensors
