// The OSMesa back end: Mesa's off-screen library, rendering with llvmpipe in the calling thread.
// Gone from Mesa 25.1 on; the default where it is built and works (render/README.md § Back ends).
// First: it declares GL's prototypes, which osmesa.h's own include of gl.h would leave out.
#include "render/internal/gl_context.hpp"
//
#include <GL/osmesa.h>

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>

namespace scout::render::internal {
namespace {

class OsmesaContext final : public GlContext {
 public:
  OsmesaContext() : GlContext(CameraBackend::osmesa) {
    const int attributes[] = {OSMESA_FORMAT,
                              OSMESA_RGBA,
                              OSMESA_DEPTH_BITS,
                              0,
                              OSMESA_STENCIL_BITS,
                              0,
                              OSMESA_ACCUM_BITS,
                              0,
                              OSMESA_PROFILE,
                              OSMESA_CORE_PROFILE,
                              OSMESA_CONTEXT_MAJOR_VERSION,
                              3,
                              OSMESA_CONTEXT_MINOR_VERSION,
                              3,
                              0};
    context_ = OSMesaCreateContextAttribs(attributes, nullptr);
    if (context_ == nullptr) {
      throw std::runtime_error(
          "PatchCamera: OSMesaCreateContextAttribs failed (an OpenGL 3.3 core context is needed; "
          "is libOSMesa with llvmpipe installed?)");
    }
    try {
      make_current();  // unbinds another back end's context first
      load([](const char* name) { return reinterpret_cast<Proc>(OSMesaGetProcAddress(name)); });
    } catch (...) {
      destroy();
      throw;
    }
  }
  ~OsmesaContext() override { destroy(); }

 private:
  bool is_current() const noexcept override { return OSMesaGetCurrentContext() == context_; }
  void bind() override {
    if (!OSMesaMakeCurrent(context_, default_buffer_.data(), GL_UNSIGNED_BYTE, 1, 1))
      throw std::runtime_error("PatchCamera: OSMesaMakeCurrent failed");
  }
  void unbind() noexcept override { OSMesaMakeCurrent(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0); }
  void destroy() noexcept {
    if (is_current()) unbind();
    forget();
    OSMesaDestroyContext(context_);
  }

  OSMesaContext context_ = nullptr;
  // OSMesa needs a colour buffer to make a context current; the camera draws into its own FBO.
  std::array<std::uint8_t, 4> default_buffer_{};
};

}  // namespace

bool osmesa_built() { return true; }
std::unique_ptr<GlContext> make_osmesa_context() { return std::make_unique<OsmesaContext>(); }

}  // namespace scout::render::internal
