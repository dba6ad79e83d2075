#include "sensors/osmesa_context.hpp"

#include <GL/osmesa.h>

#include <stdexcept>

namespace conesim::sensors {

OsMesaContext::OsMesaContext(int width_px, int height_px)
    : width_px_(width_px), height_px_(height_px) {
  // RGBA colour, 24-bit depth, 8-bit stencil, no accumulation buffer, no shared context
  context_ = OSMesaCreateContextExt(OSMESA_RGBA, 24, 8, 0, nullptr);
  if (!context_) throw std::runtime_error("OSMesa could not create an off-screen GL context");
  buffer_.resize(static_cast<size_t>(width_px) * static_cast<size_t>(height_px) * 4);
  make_current();
}

OsMesaContext::~OsMesaContext() {
  OSMesaDestroyContext(context_);
}

void OsMesaContext::make_current() {
  if (!try_make_current())
    throw std::runtime_error("OSMesa could not make the off-screen GL context current");
}

bool OsMesaContext::try_make_current() noexcept {
  return OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, width_px_, height_px_);
}

}  // namespace conesim::sensors
