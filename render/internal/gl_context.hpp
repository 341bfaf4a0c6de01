#pragma once
// Internal to render/: the GL context a camera draws in, made by one of the back ends (OSMesa or
// EGL), and the GL entry points the camera calls, loaded through that back end.
//
// Why through the back end and not by linking libGL: libOSMesa and glvnd's libOpenGL export the
// same gl* names, so a program linked with both would call one library's entry points whichever
// context is current. Entry points asked of the back end (OSMesaGetProcAddress,
// eglGetProcAddress) always dispatch to the context that back end made current, and a program
// links only the back ends (no libGL at all).
#define GL_GLEXT_PROTOTYPES  // the declarations give the pointer types (decltype); none is called
#include <GL/gl.h>
#include <GL/glext.h>

#include <memory>
#include <string>

#include "render/camera.hpp"

namespace scout::render::internal {

// Every GL function camera.cpp calls, without its gl prefix.
// clang-format off
#define SCOUT_GL_FUNCTIONS(X)                                                                     \
  X(ActiveTexture) X(AttachShader) X(BindBuffer) X(BindFramebuffer) X(BindRenderbuffer)           \
  X(BindTexture) X(BindVertexArray) X(BufferData) X(BufferSubData) X(CheckFramebufferStatus)      \
  X(CompileShader) X(CreateProgram) X(CreateShader) X(DeleteBuffers) X(DeleteFramebuffers)        \
  X(DeleteProgram) X(DeleteRenderbuffers) X(DeleteShader) X(DeleteTextures) X(DeleteVertexArrays) \
  X(Disable) X(DrawArrays) X(Enable) X(EnableVertexAttribArray) X(FramebufferRenderbuffer)        \
  X(GenBuffers) X(GenFramebuffers) X(GenRenderbuffers) X(GenTextures) X(GenVertexArrays)          \
  X(GetError) X(GetIntegerv) X(GetProgramInfoLog) X(GetProgramiv) X(GetShaderInfoLog)             \
  X(GetShaderiv) X(GetString) X(GetUniformLocation) X(LinkProgram) X(PixelStorei)                 \
  X(PointParameteri) X(ReadBuffer) X(ReadPixels) X(RenderbufferStorage) X(ShaderSource)           \
  X(TexParameterfv) X(TexParameteri) X(TexStorage3D) X(TexSubImage3D) X(Uniform1i) X(Uniform2f)   \
  X(Uniform2i) X(UseProgram) X(VertexAttribIPointer) X(VertexAttribPointer) X(Viewport)
// clang-format on

/// The GL entry points, as the back end that made the context gives them: gl.DrawArrays(...).
struct GlFunctions {
#define SCOUT_GL_MEMBER(name) decltype(&::gl##name) name = nullptr;
  SCOUT_GL_FUNCTIONS(SCOUT_GL_MEMBER)
#undef SCOUT_GL_MEMBER
};

/// A back end's context, current on the calling thread when make_current() returns. Each camera
/// owns one; the last one made current on a thread is remembered, so that a camera drawing again
/// makes no GL call to bind, and a switch between back ends first unbinds the other one (both
/// dispatch through Mesa's one libglapi, which only the back end that binds last points right).
class GlContext {
 public:
  virtual ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  CameraBackend backend() const { return backend_; }
  const GlFunctions& gl() const { return functions_; }
  /// "OSMesa: llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile) Mesa 22.3.6"
  const std::string& description() const { return description_; }
  /// Throws std::runtime_error if the back end cannot bind the context.
  void make_current();

 protected:
  explicit GlContext(CameraBackend backend) : backend_(backend) {}
  /// For the back end's constructor, after make_current(): loads the entry points through
  /// `lookup` (throws naming the first one missing) and reads the renderer's description.
  using Proc = void (*)();
  void load(Proc (*lookup)(const char*));
  /// For the back end's destructor: forgets this context if the thread remembers it.
  void forget() noexcept;
  virtual bool is_current() const noexcept = 0;  // the back end's own view
  virtual void bind() = 0;                       // throws std::runtime_error
  virtual void unbind() noexcept = 0;            // makes no context of this back end current

 private:
  CameraBackend backend_;
  GlFunctions functions_;
  std::string description_;
};

/// The back ends this build has, in `automatic`'s order.
bool osmesa_built();
bool egl_built();
/// A back end's context (OpenGL 3.3 core); std::runtime_error saying why it cannot be made.
std::unique_ptr<GlContext> make_osmesa_context();
std::unique_ptr<GlContext> make_egl_context();

/// The context for `requested`: `automatic` reads SCOUT_CAMERA_BACKEND, and where that is unset
/// or "auto", takes OSMesa where it is built and works, else EGL.
std::unique_ptr<GlContext> make_gl_context(CameraBackend requested);

}  // namespace scout::render::internal
