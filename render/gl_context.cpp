// What the back ends share: the thread's current context, the entry points, and the choice
// among the back ends (render/README.md § Back ends).
#include "render/internal/gl_context.hpp"

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

namespace scout::render {
namespace internal {
namespace {

// The context this thread made current last, of either back end (nullptr: none, or it is gone).
thread_local GlContext* thread_current = nullptr;

}  // namespace

GlContext::~GlContext() = default;

void GlContext::make_current() {
  if (thread_current == this && is_current()) return;
  // Both back ends set Mesa's one dispatch table; the other one's context is unbound first so
  // that its back end binds afresh next time instead of believing its context still current.
  if (thread_current != nullptr && thread_current != this && thread_current->backend() != backend_)
    thread_current->unbind();
  thread_current = nullptr;
  bind();
  thread_current = this;
}

void GlContext::forget() noexcept {
  if (thread_current == this) thread_current = nullptr;
}

void GlContext::load(Proc (*lookup)(const char*)) {
#define SCOUT_GL_LOAD(name)                                                                     \
  functions_.name = reinterpret_cast<decltype(functions_.name)>(lookup("gl" #name));            \
  if (functions_.name == nullptr)                                                               \
    throw std::runtime_error(std::string("PatchCamera: the ") + camera_backend_name(backend_) + \
                             " back end has no gl" #name " (an OpenGL 3.3 core context is needed)");
  SCOUT_GL_FUNCTIONS(SCOUT_GL_LOAD)
#undef SCOUT_GL_LOAD
  const auto text = [&](GLenum name) {
    const GLubyte* value = functions_.GetString(name);
    return value ? std::string(reinterpret_cast<const char*>(value)) : std::string("?");
  };
  description_ = std::string(backend_ == CameraBackend::egl ? "EGL" : "OSMesa") + ": " + text(GL_RENDERER) + "; " +
                 text(GL_VERSION);
}

#ifndef SCOUT_CAMERA_OSMESA
bool osmesa_built() { return false; }
std::unique_ptr<GlContext> make_osmesa_context() {
  throw std::runtime_error("PatchCamera: this build has no OSMesa back end (libosmesa6-dev was not found)");
}
#endif
#ifndef SCOUT_CAMERA_EGL
bool egl_built() { return false; }
std::unique_ptr<GlContext> make_egl_context() {
  throw std::runtime_error("PatchCamera: this build has no EGL back end (libegl-dev was not found)");
}
#endif

std::unique_ptr<GlContext> make_gl_context(CameraBackend requested) {
  if (requested == CameraBackend::automatic) {
    if (const char* chosen = std::getenv(kCameraBackendVariable); chosen != nullptr && *chosen != '\0') {
      try {
        requested = parse_camera_backend(chosen);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(std::string("PatchCamera: ") + kCameraBackendVariable + ": " + e.what());
      }
    }
  }
  if (requested == CameraBackend::osmesa) return make_osmesa_context();
  if (requested == CameraBackend::egl) return make_egl_context();
  // auto: OSMesa where it is built and works (the default, as before EGL), else EGL.
  std::string why;
  if (osmesa_built()) {
    try {
      return make_osmesa_context();
    } catch (const std::runtime_error& e) {
      why = e.what();
    }
  }
  if (egl_built()) {
    try {
      return make_egl_context();
    } catch (const std::runtime_error& e) {
      why += (why.empty() ? "" : "; ") + std::string(e.what());
    }
  }
  throw std::runtime_error(why.empty() ? "PatchCamera: this build has no camera back end" : why);
}

}  // namespace internal

const char* camera_backend_name(CameraBackend backend) {
  switch (backend) {
    case CameraBackend::osmesa:
      return "osmesa";
    case CameraBackend::egl:
      return "egl";
    case CameraBackend::automatic:
      break;
  }
  return "auto";
}

CameraBackend parse_camera_backend(std::string_view name) {
  if (name == "auto") return CameraBackend::automatic;
  if (name == "osmesa") return CameraBackend::osmesa;
  if (name == "egl") return CameraBackend::egl;
  throw std::invalid_argument("expected a camera back end: auto, osmesa or egl, got '" + std::string(name) + "'");
}

std::vector<CameraBackend> built_camera_backends() {
  std::vector<CameraBackend> built;
  if (internal::osmesa_built()) built.push_back(CameraBackend::osmesa);
  if (internal::egl_built()) built.push_back(CameraBackend::egl);
  return built;
}

}  // namespace scout::render
