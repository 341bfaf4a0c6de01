// The EGL back end: a context with no surface at all (EGL_KHR_surfaceless_context), drawing only
// into the camera's own framebuffer object. The display is Mesa's surfaceless platform (llvmpipe
// on a machine without a GPU, the GPU's driver where there is one) or, where an EGL has no such
// platform (NVIDIA's), the first device of EGL_EXT_platform_device. render/README.md § Back ends.
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "render/internal/gl_context.hpp"

namespace scout::render::internal {
namespace {

std::string egl_error() {
  const EGLint code = eglGetError();
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04X", static_cast<unsigned>(code));
  switch (code) {
    case EGL_BAD_ACCESS:
      return std::string("EGL_BAD_ACCESS ") + hex;
    case EGL_BAD_ALLOC:
      return std::string("EGL_BAD_ALLOC ") + hex;
    case EGL_BAD_ATTRIBUTE:
      return std::string("EGL_BAD_ATTRIBUTE ") + hex;
    case EGL_BAD_CONFIG:
      return std::string("EGL_BAD_CONFIG ") + hex;
    case EGL_BAD_CONTEXT:
      return std::string("EGL_BAD_CONTEXT ") + hex;
    case EGL_BAD_DISPLAY:
      return std::string("EGL_BAD_DISPLAY ") + hex;
    case EGL_BAD_MATCH:
      return std::string("EGL_BAD_MATCH ") + hex;
    case EGL_BAD_PARAMETER:
      return std::string("EGL_BAD_PARAMETER ") + hex;
    case EGL_NOT_INITIALIZED:
      return std::string("EGL_NOT_INITIALIZED ") + hex;
    default:
      return std::string("EGL error ") + hex;
  }
}

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t length = std::strlen(name);
  for (const char* at = std::strstr(list, name); at != nullptr; at = std::strstr(at + 1, name)) {
    if ((at == list || at[-1] == ' ') && (at[length] == ' ' || at[length] == '\0')) return true;
  }
  return false;
}

// The process's display, initialised once and never terminated: eglTerminate would take every
// other camera's context with it. `error` says why there is none.
struct Display {
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string error;
};

Display open_display() {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const auto get_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (get_display == nullptr || !has_extension(client, "EGL_EXT_platform_base"))
    return {EGL_NO_DISPLAY, "PatchCamera: this EGL has no EGL_EXT_platform_base (a surfaceless display needs it)"};
  std::string tried;
  const auto initialise = [&](EGLDisplay display, const char* what) {
    if (display == EGL_NO_DISPLAY) {
      tried += std::string(tried.empty() ? "" : "; ") + what + ": no display (" + egl_error() + ")";
      return false;
    }
    EGLint major = 0, minor = 0;
    if (eglInitialize(display, &major, &minor) != EGL_TRUE) {
      tried += std::string(tried.empty() ? "" : "; ") + what + ": eglInitialize failed (" + egl_error() + ")";
      return false;
    }
    return true;
  };
  if (has_extension(client, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay display = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (initialise(display, "the surfaceless platform")) return {display, {}};
  }
  const auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  if (query_devices != nullptr && has_extension(client, "EGL_EXT_platform_device")) {
    EGLint count = 0;
    std::vector<EGLDeviceEXT> devices(16);
    if (query_devices(static_cast<EGLint>(devices.size()), devices.data(), &count) == EGL_TRUE) {
      for (EGLint i = 0; i < count; ++i) {
        EGLDisplay display = get_display(EGL_PLATFORM_DEVICE_EXT, devices[static_cast<std::size_t>(i)], nullptr);
        if (initialise(display, "EGL device")) return {display, {}};
      }
    }
  }
  return {EGL_NO_DISPLAY, "PatchCamera: no EGL display without a window system (" +
                              (tried.empty() ? std::string("neither EGL_MESA_platform_surfaceless nor "
                                                           "EGL_EXT_platform_device is offered")
                                             : tried) +
                              ")"};
}

const Display& process_display() {
  static const Display display = open_display();  // thread-safe, once
  return display;
}

class EglContext final : public GlContext {
 public:
  EglContext() : GlContext(CameraBackend::egl) {
    const Display& shared = process_display();
    if (shared.display == EGL_NO_DISPLAY) throw std::runtime_error(shared.error);
    display_ = shared.display;
    const char* extensions = eglQueryString(display_, EGL_EXTENSIONS);
    for (const char* needed : {"EGL_KHR_surfaceless_context", "EGL_KHR_no_config_context"}) {
      if (!has_extension(extensions, needed) && !(std::strcmp(needed, "EGL_KHR_no_config_context") == 0 &&
                                                  has_extension(extensions, "EGL_MESA_configless_context")))
        throw std::runtime_error(std::string("PatchCamera: the EGL display lacks ") + needed +
                                 " (the camera draws with no surface and no config)");
    }
    if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE)
      throw std::runtime_error("PatchCamera: eglBindAPI(EGL_OPENGL_API) failed (" + egl_error() +
                               "): this EGL offers no desktop OpenGL");
    const EGLint attributes[] = {
        EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
        EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    context_ = eglCreateContext(display_, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
    if (context_ == EGL_NO_CONTEXT)
      throw std::runtime_error("PatchCamera: eglCreateContext failed (" + egl_error() +
                               "; an OpenGL 3.3 core context is needed)");
    try {
      make_current();  // unbinds another back end's context first
      load([](const char* name) { return reinterpret_cast<Proc>(eglGetProcAddress(name)); });
    } catch (...) {
      destroy();
      throw;
    }
  }
  ~EglContext() override { destroy(); }

 private:
  bool is_current() const noexcept override { return eglGetCurrentContext() == context_; }
  void bind() override {
    // eglBindAPI is per thread: a camera used from another thread binds OpenGL there too.
    if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE ||
        eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_) != EGL_TRUE)
      throw std::runtime_error("PatchCamera: eglMakeCurrent failed (" + egl_error() + ")");
  }
  void unbind() noexcept override { eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT); }
  void destroy() noexcept {
    if (is_current()) unbind();
    forget();
    eglDestroyContext(display_, context_);
  }

  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
};

}  // namespace

bool egl_built() { return true; }
std::unique_ptr<GlContext> make_egl_context() { return std::make_unique<EglContext>(); }

}  // namespace scout::render::internal
