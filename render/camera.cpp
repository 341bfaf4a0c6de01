// The patch camera: OSMesa (llvmpipe) renders every robot's m x m window in one draw of point
// sprites into an R8 tile grid, which is read back with one glReadPixels. MEASURED.md § OSMesa
// explains the choices (point sprites, texture array, R8, LP_NUM_THREADS=0).
#include "render/camera.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/worker_pool.hpp"
#include "grid/grid.hpp"
#include "render/internal/gl_context.hpp"
#include "worlds/floors.hpp"

namespace scout::render {
namespace {

using internal::GlFunctions;

constexpr int kMaxPatchPx = 64;
constexpr int kMaxFloorPx = 512;
// World files are validated against these limits before a camera is ever made.
static_assert(kMaxPatchPx == worlds::kMaxPatchPx && kMaxFloorPx == worlds::kMaxFloorPx,
              "the world-file limits must be the camera's");

// One vertex per robot: its pose as two ints, straight from the caller's PixelPose span.
static_assert(sizeof(PixelPose) == 2 * sizeof(GLint), "PixelPose is uploaded as an ivec2");
// capture_at()'s vertex: its centre as two floats, in the same buffer (8 bytes a robot as well).
static_assert(sizeof(FloorPoint) == 2 * sizeof(GLfloat), "FloorPoint is uploaded as a vec2");

// Every shader is compiled with "#define STACKED_FLOORS 0|1" (see Impl::floors_per_layer) and
// "#define WIDE_VIEW 0|1" after the version line. The vertex shader places robot i's point on the
// centre of tile i.
constexpr const char* kVersion = "#version 330 core\n";

constexpr const char* kVertexShader = R"(
layout(location = 0) in ivec2 pose;
uniform int tile_columns;
uniform int patch_px;
uniform int tile_px;  // patch_px, or the wider view's side where that is larger
uniform vec2 framebuffer_px;
#if STACKED_FLOORS
flat out ivec2 window_minus_tile;
flat out int robot;
#else
flat out vec2 window_minus_tile;
flat out float layer;
#endif
void main() {
  int robot_index = gl_VertexID;
  ivec2 tile_origin = ivec2(robot_index % tile_columns, robot_index / tile_columns) * tile_px;
#if WIDE_VIEW
  set_wide_offset(pose, tile_origin);
#endif
  // Integer division truncates, and patch_px > 0, so patch_px / 2 is floor(m / 2). GLSL int
  // arithmetic wraps on overflow: an absurd pose still lands far off the floor and reads 0.
  ivec2 window_origin = pose - ivec2(patch_px / 2);
#if STACKED_FLOORS
  window_minus_tile = window_origin - tile_origin;
  robot = robot_index;
#else
  window_minus_tile = vec2(window_origin - tile_origin);
  layer = float(robot_index);
#endif
  // The point's centre sits exactly on the tile's centre (an integer or half-integer), so its
  // square covers the tile's pixel centres and no others.
  vec2 centre = vec2(tile_origin) + 0.5 * float(tile_px);
  gl_Position = vec4(centre / framebuffer_px * 2.0 - 1.0, 0.0, 1.0);
  gl_PointSize = float(tile_px);
}
)";

// Tile pixel (dx, dy) shows floor texel window_origin + (dx, dy). Framebuffer row r is memory row
// r of the read-back, and texture row t is memory row t of the upload, so nothing is flipped:
// window row 0 is the floor's smallest y. gl_FragCoord is used rather than gl_PointCoord because
// it is an exact pixel centre, whatever the sprite origin.
//
// One floor per layer (the fast path): gl_FragCoord + (window - tile) is the texel's centre,
// t + 0.5, exactly in float; nearest sampling there returns texel t, and clamp-to-border returns
// 0 off the floor. texture() is markedly faster than texelFetch on llvmpipe.
// Stacked floors: the border would show the neighbouring floor, so texelFetch with an explicit
// bounds test instead.
constexpr const char* kFragmentShader = R"(
uniform sampler2DArray floors;
uniform vec2 inverse_floor_px;
uniform ivec2 floor_px;
uniform int floors_per_layer;
#if STACKED_FLOORS
flat in ivec2 window_minus_tile;
flat in int robot;
#else
flat in vec2 window_minus_tile;
flat in float layer;
#endif
layout(location = 0) out vec4 colour;
void main() {
#if STACKED_FLOORS
  ivec2 texel = ivec2(gl_FragCoord.xy) + window_minus_tile;
  float value = 0.0;
  if (all(greaterThanEqual(texel, ivec2(0))) && all(lessThan(texel, floor_px))) {
    int layer = robot / floors_per_layer;
    int row_offset = (robot % floors_per_layer) * floor_px.y;
    value = texelFetch(floors, ivec3(texel.x, texel.y + row_offset, layer), 0).r;
  }
#else
  vec2 texel_centre = gl_FragCoord.xy + window_minus_tile;
  float value = texture(floors, vec3(texel_centre * inverse_floor_px, layer)).r;
#endif
#if WIDE_VIEW
#if STACKED_FLOORS
  colour = vec4(value, wide_grey(robot, floors_per_layer), 0.0, 1.0);
#else
  colour = vec4(value, wide_grey(int(layer), floors_per_layer), 0.0, 1.0);
#endif
#else
  colour = vec4(value, 0.0, 0.0, 1.0);
#endif
}
)";

// capture_at(): the same tiles, sampled at continuous centres. What filtering: bilinear over
// texel centres (texel (x, y) sits at (x + 0.5, y + 0.5)), texels off the floor 0, in float, and
// rounded to the nearest grey level (halves up): the definition sample_patch_bilinear computes in
// double. GL_LINEAR is not used (llvmpipe filters in fixed point, and the border would show a
// stacked neighbour floor): the shader fetches the four texels around the sample point and
// weights them itself. The vertex shader splits the centre once per robot into a whole texel and
// a fraction (both exact in float), so that each pixel only adds integers to the texel; at a cell
// centre the fraction is 0 and the result is texel for texel capture()'s.
//
// Centres are clamped to 1024 px beyond the floor (a window is at most 64 px, so a clamped centre
// still samples only zeros), which keeps the float to int conversion in range.
constexpr const char* kBilinearVertexShader = R"(
layout(location = 0) in vec2 centre;
uniform int tile_columns;
uniform int patch_px;
uniform int tile_px;
uniform vec2 framebuffer_px;
uniform ivec2 floor_px;
flat out ivec2 window_minus_tile;
flat out vec2 fraction;
flat out int robot;
void main() {
  int robot_index = gl_VertexID;
  ivec2 tile_origin = ivec2(robot_index % tile_columns, robot_index / tile_columns) * tile_px;
#if WIDE_VIEW
  // At the cell that holds the centre (clamped as below).
  set_wide_offset(ivec2(floor(clamp(centre, vec2(-1024.0), vec2(floor_px) + 1024.0))), tile_origin);
#endif
  // Window pixel (0, 0)'s sample point in texel-centre coordinates (texel t at t + 0.5 becomes t).
  vec2 corner = clamp(centre - 0.5, vec2(-1024.0), vec2(floor_px) + 1024.0);
  vec2 whole = floor(corner);
  fraction = corner - whole;
  window_minus_tile = ivec2(whole) - ivec2(patch_px / 2) - tile_origin;
  robot = robot_index;
  vec2 tile_centre = vec2(tile_origin) + 0.5 * float(tile_px);
  gl_Position = vec4(tile_centre / framebuffer_px * 2.0 - 1.0, 0.0, 1.0);
  gl_PointSize = float(tile_px);
}
)";

// Tile pixel (dx, dy) blends texels t = (whole - floor(m/2)) + (dx, dy) .. t + (1, 1), weighted
// by the fraction. One floor per layer (the fast path): one textureGather at the corner the four
// texels share returns all four (it selects texels, it does not filter), and clamp-to-border
// returns 0 off the floor; it measured about 1.6x as fast as four texelFetch (240 robots, m = 6).
// Stacked floors: the border would show the neighbouring floor, so four texelFetch with an
// explicit bounds test. Texel values are made exact grey levels (integers in float) before
// weighting.
// Extension directives come before any declaration (so before the wider view's part).
constexpr const char* kGatherExtension = R"(
#if !STACKED_FLOORS
#extension GL_ARB_texture_gather : require
#endif
)";
constexpr const char* kBilinearFragmentShader = R"(
uniform sampler2DArray floors;
uniform ivec2 floor_px;
uniform vec2 inverse_floor_px;
uniform int floors_per_layer;
flat in ivec2 window_minus_tile;
flat in vec2 fraction;
flat in int robot;
layout(location = 0) out vec4 colour;
#if STACKED_FLOORS
float grey(ivec2 t, int layer, int row_offset) {
  if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, floor_px))) return 0.0;
  return floor(texelFetch(floors, ivec3(t.x, t.y + row_offset, layer), 0).r * 255.0 + 0.5);
}
#endif
void main() {
  ivec2 texel = ivec2(gl_FragCoord.xy) + window_minus_tile;
#if STACKED_FLOORS
  int layer = robot / floors_per_layer;
  int row_offset = (robot % floors_per_layer) * floor_px.y;
  float a = grey(texel, layer, row_offset);
  float b = grey(texel + ivec2(1, 0), layer, row_offset);
  float c = grey(texel + ivec2(0, 1), layer, row_offset);
  float d = grey(texel + ivec2(1, 1), layer, row_offset);
#else
  // The shared corner of texels t .. t + (1, 1) is t + 1 (texel centres are at t + 0.5), half a
  // texel from every centre, so the choice of texels does not hang on rounding. Gather's order:
  // x = (t.x, t.y + 1), y = (t.x + 1, t.y + 1), z = (t.x + 1, t.y), w = t.
  vec3 at = vec3((vec2(texel) + 1.0) * inverse_floor_px, float(robot));
  vec4 four = floor(textureGather(floors, at) * 255.0 + 0.5);
  float a = four.w;
  float b = four.z;
  float c = four.x;
  float d = four.y;
#endif
  float fx = fraction.x;
  float fy = fraction.y;
  float value = (1.0 - fx) * (1.0 - fy) * a + fx * (1.0 - fy) * b + (1.0 - fx) * fy * c + fx * fy * d;
#if WIDE_VIEW
  colour = vec4(floor(value + 0.5) / 255.0, wide_grey(robot, floors_per_layer), 0.0, 1.0);
#else
  colour = vec4(floor(value + 0.5) / 255.0, 0.0, 0.0, 1.0);
#endif
}
)";

// The wider view, in the same draw and the same fragments as the patches: with a wider view each
// robot's tile is max(m, wide_px) pixels a side and the framebuffer is RG8, the patch in red (its
// m x m corner) and the wider view in green (its wide_px x wide_px corner). Green pixel (i, j) of
// robot r is the mean of block (b + i, b + j) of the floor's block grid (grid::BlockGrid: blocks of
// wide_scale x wide_scale texels from the floor's corner, texels off the floor counting 0), where
// b = the block that holds the robot's cell - floor(wide_px / 2) on each axis. Each is one read of
// the floor's block means (block_means: texel (u, v) holds block (u, v)'s mean, made on the CPU
// when the floors are loaded, rounded half up exactly as wide_patch computes it; its zero border
// is every block off the floor). Measured at 240 robots, 8 x 8 of 6 x 6, against the patches
// alone (2.4 M a second): summing each block in the shader, 36 texelFetch a pixel, or four reads of
// a summed-area texture, in a tile grid of its own drawn as a second instance, ran 3 to 6 times as
// slow; one read in the patch's own fragments, read back as a second channel, is measured in the
// README (speed). Windows on the block grid, rather than centred on the cell to the pixel, keep
// the table at one texel a block (a table of every block position was 36 times as large at
// scale 6, and making and uploading it took 0.7 ms of a 240-robot reset at 100 x 100), and let
// the environment keep the coarse map at one byte a block.
//
// These parts come before the body of both vertex shaders and both fragment shaders (WIDE_VIEW 0
// leaves them out).
constexpr const char* kWideVertexPart = R"(
#if WIDE_VIEW
uniform int wide_px;
uniform int wide_scale;
flat out ivec2 wide_offset;  // tile pixel p shows block p + wide_offset
void set_wide_offset(ivec2 cell, ivec2 tile_origin) {
  // Floor division, as grid::BlockGrid::block_of (GLSL's truncates toward zero): a cell left of or
  // above the floor lies in a block before block 0.
  ivec2 below = ivec2(lessThan(cell, ivec2(0)));
  ivec2 block = (cell + below) / wide_scale - below;
  wide_offset = block - ivec2(wide_px / 2) - tile_origin;
}
#endif
)";

constexpr const char* kWideFragmentPart = R"(
#if WIDE_VIEW
uniform sampler2DArray block_means;
uniform int wide_scale;
uniform ivec2 block_means_px;         // the block grid's columns and rows
uniform vec2 inverse_block_means_px;  // 1 / block_means_px
flat in ivec2 wide_offset;
float wide_grey(int wide_robot, int floors_per_layer) {
  // The block's texel in the table. GLSL int arithmetic wraps: a block far off the floor (an
  // absurd pose) still lands far outside the table.
  ivec2 t = ivec2(gl_FragCoord.xy) + wide_offset;
#if STACKED_FLOORS
  if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, block_means_px))) return 0.0;
  int row_offset = (wide_robot % floors_per_layer) * block_means_px.y;
  return texelFetch(block_means, ivec3(t.x, t.y + row_offset, wide_robot / floors_per_layer), 0).r;
#else
  // At the texel's centre, nearest: texel t exactly, and the zero border off the table.
  return texture(block_means, vec3((vec2(t) + 0.5) * inverse_block_means_px, float(wide_robot))).r;
#endif
}
#endif
)";

std::string shader_log(const GlFunctions& gl, GLuint shader) {
  GLint length = 0;
  gl.GetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
  gl.GetShaderInfoLog(shader, length, nullptr, log.data());
  return log.c_str();
}

std::string program_log(const GlFunctions& gl, GLuint program) {
  GLint length = 0;
  gl.GetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
  gl.GetProgramInfoLog(program, length, nullptr, log.data());
  return log.c_str();
}

// A shader's source: the version, its defines, `extensions`, the wider view's part, then `body`.
GLuint compile_shader(const GlFunctions& gl, GLenum kind, const char* body, bool stacked_floors, bool wide_view,
                      const char* name, const char* extensions = "") {
  GLuint shader = gl.CreateShader(kind);
  const char* stacked = stacked_floors ? "#define STACKED_FLOORS 1\n" : "#define STACKED_FLOORS 0\n";
  const char* wide = wide_view ? "#define WIDE_VIEW 1\n" : "#define WIDE_VIEW 0\n";
  const char* wide_part = kind == GL_VERTEX_SHADER ? kWideVertexPart : kWideFragmentPart;
  const char* sources[] = {kVersion, stacked, wide, extensions, wide_part, body};
  gl.ShaderSource(shader, 6, sources, nullptr);
  gl.CompileShader(shader);
  GLint ok = GL_FALSE;
  gl.GetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    std::string log = shader_log(gl, shader);
    gl.DeleteShader(shader);
    throw std::runtime_error(std::string("PatchCamera: the ") + name + " shader does not compile: " + log);
  }
  return shader;
}

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("PatchCamera: " + message);
}

// For the per-call checks: the message is only built when the check fails, so that a capture
// that passes them allocates nothing.
[[noreturn]] void fail(const std::string& message) { throw std::invalid_argument("PatchCamera: " + message); }

// Whether a floor row has a pixel that is not black: 8 bytes at a time, as most rows of a floor
// larger than its digits are black and every row of every floor is tested as it is loaded.
bool has_ink(const std::uint8_t* row, int n) {
  int i = 0;
  std::uint64_t any = 0;
  for (; i + 8 <= n; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, row + i, sizeof word);
    any |= word;
  }
  for (; i < n; ++i) any |= row[i];
  return any != 0;
}

}  // namespace

struct PatchCamera::Impl {
  int floor_width_px = 0;
  int floor_height_px = 0;
  int patch_px = 0;
  int max_robots = 0;
  WideView wide;     // px 0: no wider view
  int tile_px = 0;   // a robot's tile: max(patch_px, wide.px) a side
  int channels = 1;  // the framebuffer's: R8 (the patches), RG8 with a wider view (green)
  // llvmpipe allows 2048 array layers; beyond that, several floors are stacked in one layer
  // (they are contiguous in the caller's buffer, so the upload stays one call).
  int floors_per_layer = 1;
  int layers = 0;
  int tile_columns = 0;
  int tile_rows = 0;
  int framebuffer_width_px = 0;
  int framebuffer_height_px = 0;
  int floors_loaded = 0;

  // The back end's context (OSMesa or EGL) and the GL entry points it gave.
  std::unique_ptr<internal::GlContext> context;
  internal::GlFunctions gl;
  GLuint vertex_array = 0;
  GLuint pose_buffer = 0;
  GLuint floor_texture = 0;
  GLuint framebuffer = 0;
  GLuint colour_buffer = 0;
  // The wider view's block means, one texel a block of the floor's block grid (columns x rows, an
  // R8 image per floor laid out as the floors are); `block_means_upload` is their CPU copy, grown
  // to the largest batch loaded.
  GLuint block_means_texture = 0;
  std::vector<std::uint8_t> block_means_upload;
  grid::BlockGrid blocks() const {
    return grid::BlockGrid::over({.width_px = floor_width_px, .height_px = floor_height_px}, wide.scale);
  }
  int block_means_width_px() const { return blocks().columns; }
  int block_means_height_px() const { return blocks().rows; }
  GLuint program = 0;
  // capture_at(): its own program and vertex array (the centres are floats in pose_buffer).
  GLuint bilinear_program = 0;
  GLuint centre_vertex_array = 0;
  bool bilinear_bound = false;          // which program and vertex array are bound now
  std::vector<std::uint8_t> read_back;  // the tile grid, framebuffer_width_px wide
  std::string description;

  void make_current() { context->make_current(); }

  void create_context(CameraBackend backend) {
    // llvmpipe reads LP_NUM_THREADS when its screen is created; 0 (render on the calling thread)
    // is fastest for frames this small. A user's own setting wins.
    setenv("LP_NUM_THREADS", "0", 0);
    context = internal::make_gl_context(backend);
    gl = context->gl();
    description = context->description();
  }

  GLuint link_program(const char* vertex_body, const char* fragment_body, const char* fragment_extensions = "") {
    const bool stacked = floors_per_layer > 1;
    const bool wide_view = wide.px > 0;
    GLuint vertex = compile_shader(gl, GL_VERTEX_SHADER, vertex_body, stacked, wide_view, "vertex");
    GLuint fragment = 0;
    try {
      fragment =
          compile_shader(gl, GL_FRAGMENT_SHADER, fragment_body, stacked, wide_view, "fragment", fragment_extensions);
    } catch (...) {
      gl.DeleteShader(vertex);
      throw;
    }
    GLuint linked = gl.CreateProgram();
    gl.AttachShader(linked, vertex);
    gl.AttachShader(linked, fragment);
    gl.LinkProgram(linked);
    gl.DeleteShader(vertex);
    gl.DeleteShader(fragment);
    GLint ok = GL_FALSE;
    gl.GetProgramiv(linked, GL_LINK_STATUS, &ok);
    if (ok != GL_TRUE) {
      std::string log = program_log(gl, linked);
      gl.DeleteProgram(linked);
      throw std::runtime_error("PatchCamera: the shader program does not link: " + log);
    }
    gl.UseProgram(linked);
    gl.Uniform1i(gl.GetUniformLocation(linked, "tile_columns"), tile_columns);
    gl.Uniform1i(gl.GetUniformLocation(linked, "patch_px"), patch_px);
    gl.Uniform1i(gl.GetUniformLocation(linked, "tile_px"), tile_px);
    gl.Uniform2f(gl.GetUniformLocation(linked, "framebuffer_px"), static_cast<float>(framebuffer_width_px),
                 static_cast<float>(framebuffer_height_px));
    // Unused uniforms are optimised away; glUniform* at location -1 is a no-op.
    gl.Uniform2i(gl.GetUniformLocation(linked, "floor_px"), floor_width_px, floor_height_px);
    gl.Uniform2f(gl.GetUniformLocation(linked, "inverse_floor_px"), 1.0f / static_cast<float>(floor_width_px),
                 1.0f / static_cast<float>(floor_height_px));
    gl.Uniform1i(gl.GetUniformLocation(linked, "floors_per_layer"), floors_per_layer);
    gl.Uniform1i(gl.GetUniformLocation(linked, "floors"), 0);
    gl.Uniform1i(gl.GetUniformLocation(linked, "block_means"), 1);
    gl.Uniform2i(gl.GetUniformLocation(linked, "block_means_px"), block_means_width_px(), block_means_height_px());
    gl.Uniform2f(gl.GetUniformLocation(linked, "inverse_block_means_px"),
                 1.0f / static_cast<float>(block_means_width_px()), 1.0f / static_cast<float>(block_means_height_px()));
    gl.Uniform1i(gl.GetUniformLocation(linked, "wide_px"), wide.px);
    gl.Uniform1i(gl.GetUniformLocation(linked, "wide_scale"), wide.scale);
    return linked;
  }

  // capture()'s program only: capture_at()'s (which needs GL_ARB_texture_gather) is linked on
  // its first use, so that a GL without that extension still runs exact worlds.
  void create_programs() {
    program = link_program(kVertexShader, kFragmentShader);
    bind_crop();
  }

  // One draw for the batch: a point per robot.
  void draw(int robots) { gl.DrawArrays(GL_POINTS, 0, robots); }

  // capture() and capture_at() each bind their program and vertex array only when the other
  // one drew last, so a run of capture() calls makes no extra GL calls. pose_buffer stays bound
  // to GL_ARRAY_BUFFER throughout (that binding is not vertex-array state).
  void bind_crop() {
    gl.UseProgram(program);
    gl.BindVertexArray(vertex_array);
    bilinear_bound = false;
  }

  void bind_bilinear() {
    if (bilinear_program == 0)
      bilinear_program = link_program(kBilinearVertexShader, kBilinearFragmentShader, kGatherExtension);
    gl.UseProgram(bilinear_program);
    gl.BindVertexArray(centre_vertex_array);
    bilinear_bound = true;
  }

  // The wider view's block means (load_block_means fills them): an R8 array laid out as the
  // floors, sampled like them (nearest at texel centres, the zero border off the table).
  void create_block_means_texture(GLint max_texture_px, const GLfloat* border) {
    if (static_cast<long long>(floors_per_layer) * block_means_height_px() > max_texture_px ||
        block_means_width_px() > max_texture_px) {
      throw std::runtime_error("PatchCamera: " + std::to_string(max_robots) + " wider views' tables of " +
                               std::to_string(block_means_height_px()) + " rows do not fit the GL texture limits");
    }
    gl.ActiveTexture(GL_TEXTURE1);
    gl.GenTextures(1, &block_means_texture);
    gl.BindTexture(GL_TEXTURE_2D_ARRAY, block_means_texture);
    gl.TexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_R8, block_means_width_px(), block_means_height_px() * floors_per_layer,
                    layers);
    // As the floors: nearest at texel centres, and the zero border for blocks off the floor.
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
    gl.TexParameterfv(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_BORDER_COLOR, border);
    gl.ActiveTexture(GL_TEXTURE0);
  }

  void create_buffers() {
    gl.GenVertexArrays(1, &vertex_array);
    gl.BindVertexArray(vertex_array);
    gl.GenBuffers(1, &pose_buffer);
    gl.BindBuffer(GL_ARRAY_BUFFER, pose_buffer);
    gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(max_robots) * sizeof(PixelPose), nullptr, GL_STREAM_DRAW);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribIPointer(0, 2, GL_INT, sizeof(PixelPose), nullptr);
    gl.GenVertexArrays(1, &centre_vertex_array);
    gl.BindVertexArray(centre_vertex_array);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(FloorPoint), nullptr);
    gl.BindVertexArray(vertex_array);

    GLint max_layers = 0;
    GLint max_texture_px = 0;
    gl.GetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
    gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture_px);
    max_layers = std::max(max_layers, 1);
    floors_per_layer = (max_robots + max_layers - 1) / max_layers;
    layers = (max_robots + floors_per_layer - 1) / floors_per_layer;
    if (static_cast<long long>(floors_per_layer) * floor_height_px > max_texture_px) {
      throw std::runtime_error("PatchCamera: " + std::to_string(max_robots) + " floors of " +
                               std::to_string(floor_height_px) + " rows do not fit the GL texture limits");
    }
    gl.ActiveTexture(GL_TEXTURE0);
    gl.GenTextures(1, &floor_texture);
    gl.BindTexture(GL_TEXTURE_2D_ARRAY, floor_texture);
    gl.TexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_R8, floor_width_px, floor_height_px * floors_per_layer, layers);
    // Nearest at texel centres is the exact crop; the zero border is the off-floor black.
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
    gl.TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
    const GLfloat border[] = {0.0f, 0.0f, 0.0f, 0.0f};
    gl.TexParameterfv(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_BORDER_COLOR, border);
    if (wide.px > 0) create_block_means_texture(max_texture_px, border);

    GLint max_renderbuffer_px = 0;
    gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_renderbuffer_px);
    if (framebuffer_width_px > max_renderbuffer_px || framebuffer_height_px > max_renderbuffer_px) {
      throw std::runtime_error("PatchCamera: a tile grid of " + std::to_string(framebuffer_width_px) + " x " +
                               std::to_string(framebuffer_height_px) + " px exceeds the GL renderbuffer limit");
    }
    gl.GenRenderbuffers(1, &colour_buffer);
    gl.BindRenderbuffer(GL_RENDERBUFFER, colour_buffer);
    gl.RenderbufferStorage(GL_RENDERBUFFER, channels == 2 ? GL_RG8 : GL_R8, framebuffer_width_px,
                           framebuffer_height_px);
    gl.GenFramebuffers(1, &framebuffer);
    gl.BindFramebuffer(GL_FRAMEBUFFER, framebuffer);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour_buffer);
    if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      throw std::runtime_error("PatchCamera: the R8/RG8 framebuffer is incomplete");
    }
    gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
    gl.Viewport(0, 0, framebuffer_width_px, framebuffer_height_px);

    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.Enable(GL_PROGRAM_POINT_SIZE);
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_BLEND);
    // The shader works from gl_FragCoord, not gl_PointCoord; the origin is set anyway so that
    // sprite coordinates, if ever used, run the same way as framebuffer rows.
    gl.PointParameteri(GL_POINT_SPRITE_COORD_ORIGIN, GL_LOWER_LEFT);

    read_back.assign(static_cast<std::size_t>(framebuffer_width_px) * framebuffer_height_px * channels, 0);
  }

  // Floors a worker takes at a time when the block means are spread over a pool.
  static constexpr int kFloorsPerChunk = 8;

  // One floor's block means into `means` (one byte a block of blocks(), row-major): the mean of the
  // block's scale x scale texels, those off the floor 0, rounded half up as wide_patch does. Rows
  // without ink add nothing and are skipped (a floor larger than its digits is mostly black). Reads
  // nothing of the camera's but its sizes, so floors are made side by side.
  void block_means_of(const std::uint8_t* floor, std::uint8_t* means) const {
    const int w = floor_width_px, h = floor_height_px, s = wide.scale;
    const grid::BlockGrid grid = blocks();
    const int n = s * s;
    thread_local std::vector<int> sums;  // one block row's, per thread (grown once)
    sums.resize(static_cast<std::size_t>(grid.columns));
    for (int v = 0; v < grid.rows; ++v) {
      std::fill(sums.begin(), sums.end(), 0);
      for (int y = v * s; y < std::min((v + 1) * s, h); ++y) {
        const std::uint8_t* row = floor + static_cast<std::size_t>(y) * w;
        if (!has_ink(row, w)) continue;
        for (int u = 0; u < grid.columns; ++u) {
          int sum = 0;
          for (int x = u * s; x < std::min((u + 1) * s, w); ++x) sum += row[x];
          sums[static_cast<std::size_t>(u)] += sum;
        }
      }
      std::uint8_t* out = means + static_cast<std::size_t>(v) * grid.columns;
      for (int u = 0; u < grid.columns; ++u)
        out[u] = static_cast<std::uint8_t>((2 * sums[static_cast<std::size_t>(u)] + n) / (2 * n));
    }
  }

  // The wider view's block means of `count` floors (block_means_of, floor after floor, spread over
  // `pool`'s threads where one is given), uploaded like the floors: whole layers in one call.
  void load_block_means(std::span<const std::uint8_t> floors, int count, core::WorkerPool* pool) {
    const int mw = block_means_width_px(), mh = block_means_height_px();
    const std::size_t table = static_cast<std::size_t>(mw) * static_cast<std::size_t>(mh);
    if (block_means_upload.size() < table * static_cast<std::size_t>(count))
      block_means_upload.resize(table * static_cast<std::size_t>(count));
    const std::size_t floor_bytes =
        static_cast<std::size_t>(floor_width_px) * static_cast<std::size_t>(floor_height_px);
    auto one_floor = [&](int f) {
      block_means_of(floors.data() + floor_bytes * static_cast<std::size_t>(f),
                     block_means_upload.data() + table * static_cast<std::size_t>(f));
    };
    if (pool != nullptr) {
      pool->parallel_for(count, kFloorsPerChunk, one_floor);
    } else {
      for (int f = 0; f < count; ++f) one_floor(f);
    }
    gl.ActiveTexture(GL_TEXTURE1);
    const int whole_layers = count / floors_per_layer;
    const int rest = count % floors_per_layer;
    if (whole_layers > 0) {
      gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, mw, mh * floors_per_layer, whole_layers, GL_RED,
                       GL_UNSIGNED_BYTE, block_means_upload.data());
    }
    if (rest > 0) {
      const std::size_t offset =
          table * static_cast<std::size_t>(whole_layers) * static_cast<std::size_t>(floors_per_layer);
      gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, whole_layers, mw, mh * rest, 1, GL_RED, GL_UNSIGNED_BYTE,
                       block_means_upload.data() + offset);
    }
    gl.ActiveTexture(GL_TEXTURE0);
  }

  // replace_floors' block means: each new floor's made into its slot's place in the CPU copy and
  // uploaded there (floor after floor's made side by side on `pool` where one is given).
  void replace_block_means(std::span<const int> slots, std::span<const std::uint8_t> floors, core::WorkerPool* pool) {
    const int mw = block_means_width_px(), mh = block_means_height_px();
    const std::size_t table = static_cast<std::size_t>(mw) * static_cast<std::size_t>(mh);
    const std::size_t floor_bytes =
        static_cast<std::size_t>(floor_width_px) * static_cast<std::size_t>(floor_height_px);
    auto one_floor = [&](int k) {
      block_means_of(floors.data() + floor_bytes * static_cast<std::size_t>(k),
                     block_means_upload.data() + table * static_cast<std::size_t>(slots[k]));
    };
    const int count = static_cast<int>(slots.size());
    if (pool != nullptr) {
      pool->parallel_for(count, kFloorsPerChunk, one_floor);
    } else {
      for (int k = 0; k < count; ++k) one_floor(k);
    }
    gl.ActiveTexture(GL_TEXTURE1);
    for (const int slot : slots)
      gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, (slot % floors_per_layer) * mh, slot / floors_per_layer, mw, mh, 1,
                       GL_RED, GL_UNSIGNED_BYTE, block_means_upload.data() + table * static_cast<std::size_t>(slot));
    gl.ActiveTexture(GL_TEXTURE0);
  }

  // capture()'s and capture_at()'s argument checks; `what` names the call, `items` its points.
  void check_batch(const char* what, const char* items, std::size_t count, std::size_t patches_size) const {
    const std::size_t patch_bytes = static_cast<std::size_t>(patch_px) * static_cast<std::size_t>(patch_px);
    if (!(count <= static_cast<std::size_t>(max_robots)))
      fail(std::string(what) + ": " + std::to_string(count) + " " + items + " exceed max_robots " +
           std::to_string(max_robots));
    if (!(count <= static_cast<std::size_t>(floors_loaded)))
      fail(std::string(what) + ": " + std::to_string(count) + " " + items + " but only " +
           std::to_string(floors_loaded) + " floors loaded");
    if (!(patches_size == count * patch_bytes))
      fail(std::string(what) + ": patches must hold " + std::to_string(count * patch_bytes) + " bytes (" +
           std::to_string(count) + " patches of " + std::to_string(patch_px) + " x " + std::to_string(patch_px) +
           "), got " + std::to_string(patches_size));
  }

  // The wider view's buffer: empty (not asked for), or one wide.px^2 window per robot of a camera
  // that has the view.
  void check_wide(const char* what, std::size_t count, std::size_t wide_size) const {
    if (wide_size == 0) return;
    const std::size_t bytes = static_cast<std::size_t>(wide.px) * static_cast<std::size_t>(wide.px);
    if (wide.px == 0) fail(std::string(what) + ": wide_patches given, but this camera has no wider view");
    if (!(wide_size == count * bytes))
      fail(std::string(what) + ": wide_patches must hold " + std::to_string(count * bytes) + " bytes (" +
           std::to_string(count) + " windows of " + std::to_string(wide.px) + " x " + std::to_string(wide.px) +
           "), got " + std::to_string(wide_size));
  }

  // Reads the drawn tiles back with one glReadPixels and copies them out, robot after robot: the
  // patches from red, and the wider view from green into `wide_out` where it is asked for.
  void read_tiles(int robots, std::uint8_t* out, std::uint8_t* wide_out = nullptr) {
    // Only the tile rows that hold drawn tiles are read.
    const int used_tile_rows = (robots + tile_columns - 1) / tile_columns;
    const std::size_t row_bytes = static_cast<std::size_t>(framebuffer_width_px) * channels;
    gl.ReadPixels(0, 0, framebuffer_width_px, used_tile_rows * tile_px, channels == 2 ? GL_RG : GL_RED,
                  GL_UNSIGNED_BYTE, read_back.data());
    // Channel `channel` of a side x side corner of each robot's tile.
    const auto copy_out = [&](std::uint8_t* to, int side, int channel) {
      const std::size_t t = static_cast<std::size_t>(tile_px);
      for (int robot = 0; robot < robots; ++robot) {
        const std::size_t tile_x = static_cast<std::size_t>(robot % tile_columns) * t;
        const std::size_t tile_y = static_cast<std::size_t>(robot / tile_columns) * t;
        const std::uint8_t* tile = read_back.data() + tile_y * row_bytes + tile_x * channels + channel;
        for (int row = 0; row < side; ++row) {
          const std::uint8_t* from = tile + static_cast<std::size_t>(row) * row_bytes;
          if (channels == 1) {
            std::memcpy(to, from, static_cast<std::size_t>(side));
            to += side;
          } else {
            for (int column = 0; column < side; ++column) *to++ = from[2 * column];
          }
        }
      }
    };
    copy_out(out, patch_px, 0);
    if (wide_out) copy_out(wide_out, wide.px, 1);
  }

  void release() noexcept {
    if (context == nullptr) return;
    try {
      make_current();
      if (program != 0) gl.DeleteProgram(program);
      if (bilinear_program != 0) gl.DeleteProgram(bilinear_program);
      if (framebuffer != 0) gl.DeleteFramebuffers(1, &framebuffer);
      if (colour_buffer != 0) gl.DeleteRenderbuffers(1, &colour_buffer);
      if (floor_texture != 0) gl.DeleteTextures(1, &floor_texture);
      if (block_means_texture != 0) gl.DeleteTextures(1, &block_means_texture);
      if (pose_buffer != 0) gl.DeleteBuffers(1, &pose_buffer);
      if (vertex_array != 0) gl.DeleteVertexArrays(1, &vertex_array);
      if (centre_vertex_array != 0) gl.DeleteVertexArrays(1, &centre_vertex_array);
    } catch (const std::exception&) {
      // The context cannot be bound: destroying it frees what it holds all the same.
    }
    context.reset();
  }
};

PatchCamera::PatchCamera(int floor_width_px, int floor_height_px, int patch_px, int max_robots, WideView wide,
                         CameraBackend backend)
    : impl_(std::make_unique<Impl>()) {
  require(floor_width_px > 0 && floor_width_px <= kMaxFloorPx,
          "floor width must be 1.." + std::to_string(kMaxFloorPx) + " px, got " + std::to_string(floor_width_px));
  require(floor_height_px > 0 && floor_height_px <= kMaxFloorPx,
          "floor height must be 1.." + std::to_string(kMaxFloorPx) + " px, got " + std::to_string(floor_height_px));
  require(patch_px > 0 && patch_px <= kMaxPatchPx,
          "patch size must be 1.." + std::to_string(kMaxPatchPx) + " px, got " + std::to_string(patch_px));
  require(max_robots > 0 && max_robots <= kMaxCameraRobots,
          "max_robots must be 1.." + std::to_string(kMaxCameraRobots) + ", got " + std::to_string(max_robots));
  require(wide.px >= 0 && wide.px <= kMaxPatchPx,
          "the wider view must be 0.." + std::to_string(kMaxPatchPx) + " px, got " + std::to_string(wide.px));
  require(wide.scale >= 1 && wide.scale <= kMaxWideScale,
          "the wider view's scale must be 1.." + std::to_string(kMaxWideScale) + ", got " + std::to_string(wide.scale));
  Impl& impl = *impl_;
  impl.floor_width_px = floor_width_px;
  impl.floor_height_px = floor_height_px;
  impl.patch_px = patch_px;
  impl.max_robots = max_robots;
  // A near-square grid keeps both framebuffer sides small (at most 64 tiles of 64 px).
  impl.tile_columns = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(max_robots))));
  impl.tile_rows = (max_robots + impl.tile_columns - 1) / impl.tile_columns;
  impl.wide = wide;
  impl.tile_px = std::max(patch_px, wide.px);
  impl.channels = wide.px > 0 ? 2 : 1;
  // With a wider view each tile holds both windows, the patch in red and the wider view in green.
  impl.framebuffer_width_px = impl.tile_columns * impl.tile_px;
  impl.framebuffer_height_px = impl.tile_rows * impl.tile_px;
  try {
    impl.create_context(backend);
    // Buffers first: they settle floors_per_layer, which the programs' uniforms need.
    impl.create_buffers();
    impl.create_programs();
    if (GLenum error = impl.gl.GetError(); error != GL_NO_ERROR) {
      throw std::runtime_error("PatchCamera: GL error " + std::to_string(error) + " while setting up");
    }
  } catch (...) {
    impl.release();
    throw;
  }
}

PatchCamera::~PatchCamera() {
  if (impl_) impl_->release();
}

void PatchCamera::load_floors(std::span<const std::uint8_t> floors, int count, core::WorkerPool* pool) {
  Impl& impl = *impl_;
  if (!(count > 0 && count <= impl.max_robots))
    fail("load_floors: count must be 1.." + std::to_string(impl.max_robots) + ", got " + std::to_string(count));
  const std::size_t floor_bytes =
      static_cast<std::size_t>(impl.floor_width_px) * static_cast<std::size_t>(impl.floor_height_px);
  if (!(floors.size() == floor_bytes * static_cast<std::size_t>(count)))
    fail("load_floors: expected " + std::to_string(count) + " floors of " + std::to_string(impl.floor_width_px) +
         " x " + std::to_string(impl.floor_height_px) + " = " +
         std::to_string(floor_bytes * static_cast<std::size_t>(count)) + " bytes, got " +
         std::to_string(floors.size()));
  impl.make_current();
  // Floors stacked in a layer are contiguous in memory, so whole layers go up in one call; only
  // a final, partly filled layer (possible when floors_per_layer > 1) needs a second.
  const int whole_layers = count / impl.floors_per_layer;
  const int rest = count % impl.floors_per_layer;
  if (whole_layers > 0) {
    impl.gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, impl.floor_width_px,
                          impl.floor_height_px * impl.floors_per_layer, whole_layers, GL_RED, GL_UNSIGNED_BYTE,
                          floors.data());
  }
  if (rest > 0) {
    const std::size_t offset =
        floor_bytes * static_cast<std::size_t>(whole_layers) * static_cast<std::size_t>(impl.floors_per_layer);
    impl.gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, whole_layers, impl.floor_width_px, impl.floor_height_px * rest,
                          1, GL_RED, GL_UNSIGNED_BYTE, floors.data() + offset);
  }
  if (impl.wide.px > 0) impl.load_block_means(floors, count, pool);
  impl.floors_loaded = count;
}

void PatchCamera::replace_floors(std::span<const int> slots, std::span<const std::uint8_t> floors,
                                 core::WorkerPool* pool) {
  Impl& impl = *impl_;
  const std::size_t floor_bytes =
      static_cast<std::size_t>(impl.floor_width_px) * static_cast<std::size_t>(impl.floor_height_px);
  if (!(floors.size() == floor_bytes * slots.size()))
    fail("replace_floors: expected " + std::to_string(slots.size()) + " floors of " +
         std::to_string(impl.floor_width_px) + " x " + std::to_string(impl.floor_height_px) + " = " +
         std::to_string(floor_bytes * slots.size()) + " bytes, got " + std::to_string(floors.size()));
  std::vector<bool> named(static_cast<std::size_t>(impl.floors_loaded), false);
  for (const int slot : slots) {
    if (!(slot >= 0 && slot < impl.floors_loaded))
      fail("replace_floors: slot " + std::to_string(slot) + " is not one of the " + std::to_string(impl.floors_loaded) +
           " floors loaded");
    if (named[static_cast<std::size_t>(slot)]) fail("replace_floors: slot " + std::to_string(slot) + " named twice");
    named[static_cast<std::size_t>(slot)] = true;
  }
  if (slots.empty()) return;
  impl.make_current();
  // Slot s lies in layer s / floors_per_layer, from row (s % floors_per_layer) x height.
  for (std::size_t k = 0; k < slots.size(); ++k) {
    const int slot = slots[k];
    impl.gl.TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, (slot % impl.floors_per_layer) * impl.floor_height_px,
                          slot / impl.floors_per_layer, impl.floor_width_px, impl.floor_height_px, 1, GL_RED,
                          GL_UNSIGNED_BYTE, floors.data() + floor_bytes * k);
  }
  if (impl.wide.px > 0) impl.replace_block_means(slots, floors, pool);
}

void PatchCamera::capture(std::span<const PixelPose> poses, std::span<std::uint8_t> patches,
                          std::span<std::uint8_t> wide_patches) {
  Impl& impl = *impl_;
  impl.check_batch("capture", "poses", poses.size(), patches.size());
  impl.check_wide("capture", poses.size(), wide_patches.size());
  if (poses.empty()) return;
  impl.make_current();
  if (impl.bilinear_bound) impl.bind_crop();

  const int robots = static_cast<int>(poses.size());
  impl.gl.BufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(poses.size_bytes()), poses.data());
  impl.draw(robots);
  const bool wide = !wide_patches.empty();
  impl.read_tiles(robots, patches.data(), wide ? wide_patches.data() : nullptr);
}

void PatchCamera::capture_at(std::span<const FloorPoint> centres, std::span<std::uint8_t> patches,
                             std::span<std::uint8_t> wide_patches) {
  Impl& impl = *impl_;
  impl.check_batch("capture_at", "centres", centres.size(), patches.size());
  impl.check_wide("capture_at", centres.size(), wide_patches.size());
  for (std::size_t i = 0; i < centres.size(); ++i) {
    if (!(std::isfinite(centres[i].x) && std::isfinite(centres[i].y)))
      fail("capture_at: centre " + std::to_string(i) + " is not finite (" + std::to_string(centres[i].x) + ", " +
           std::to_string(centres[i].y) + ")");
  }
  if (centres.empty()) return;
  impl.make_current();
  if (!impl.bilinear_bound) impl.bind_bilinear();

  const int robots = static_cast<int>(centres.size());
  impl.gl.BufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(centres.size_bytes()), centres.data());
  impl.draw(robots);
  const bool wide = !wide_patches.empty();
  impl.read_tiles(robots, patches.data(), wide ? wide_patches.data() : nullptr);
}

int PatchCamera::patch_px() const { return impl_->patch_px; }

WideView PatchCamera::wide_view() const { return impl_->wide; }

int PatchCamera::max_robots() const { return impl_->max_robots; }

std::string PatchCamera::gl_description() const { return impl_->description; }

CameraBackend PatchCamera::backend() const { return impl_->context->backend(); }

void crop_patch(const std::uint8_t* floor, int floor_width_px, int floor_height_px, int patch_px, PixelPose pose,
                std::uint8_t* patch_out) {
  // 64-bit so that any int pose is safe; off-floor pixels are 0.
  const long long left = static_cast<long long>(pose.x) - patch_px / 2;
  const long long top = static_cast<long long>(pose.y) - patch_px / 2;
  for (int row = 0; row < patch_px; ++row) {
    const long long y = top + row;
    for (int column = 0; column < patch_px; ++column) {
      const long long x = left + column;
      const bool on_floor = x >= 0 && x < floor_width_px && y >= 0 && y < floor_height_px;
      patch_out[row * patch_px + column] = on_floor ? floor[y * floor_width_px + x] : std::uint8_t{0};
    }
  }
}

void sample_patch_bilinear(const std::uint8_t* floor, int floor_width_px, int floor_height_px, int patch_px,
                           FloorPoint centre, std::uint8_t* patch_out) {
  // Texel (x, y) off the floor is 0.
  auto grey = [&](long long x, long long y) -> double {
    const bool on_floor = x >= 0 && x < floor_width_px && y >= 0 && y < floor_height_px;
    return on_floor ? floor[y * floor_width_px + x] : 0.0;
  };
  const int half = patch_px / 2;
  for (int row = 0; row < patch_px; ++row) {
    // The sample point in texel-centre coordinates: texel t's centre is t + 0.5.
    const double v = static_cast<double>(centre.y) + (row - half) - 0.5;
    for (int column = 0; column < patch_px; ++column) {
      const double u = static_cast<double>(centre.x) + (column - half) - 0.5;
      std::uint8_t value = 0;
      // Beyond one texel off the floor all four neighbours are 0 (this also keeps the integer
      // conversion in range for any float, and a NaN reads 0).
      if (u > -1.0 && u < floor_width_px && v > -1.0 && v < floor_height_px) {
        const double x0 = std::floor(u);
        const double y0 = std::floor(v);
        const double fx = u - x0;
        const double fy = v - y0;
        const auto x = static_cast<long long>(x0);
        const auto y = static_cast<long long>(y0);
        const double blend = (1.0 - fx) * (1.0 - fy) * grey(x, y) + fx * (1.0 - fy) * grey(x + 1, y) +
                             (1.0 - fx) * fy * grey(x, y + 1) + fx * fy * grey(x + 1, y + 1);
        // Round to nearest, halves up; the blend lies in [0, 255].
        value = static_cast<std::uint8_t>(std::floor(blend + 0.5));
      }
      patch_out[row * patch_px + column] = value;
    }
  }
}

void wide_patch(const std::uint8_t* floor, int floor_width_px, int floor_height_px, WideView wide, PixelPose cell,
                std::uint8_t* wide_out) {
  const grid::BlockGrid grid =
      grid::BlockGrid::over({.width_px = floor_width_px, .height_px = floor_height_px}, wide.scale);
  const long long first_column = static_cast<long long>(grid.block_of(cell.x)) - wide.px / 2;
  const long long first_row = static_cast<long long>(grid.block_of(cell.y)) - wide.px / 2;
  const long long n = static_cast<long long>(wide.scale) * wide.scale;
  for (int row = 0; row < wide.px; ++row) {
    for (int column = 0; column < wide.px; ++column) {
      long long sum = 0;
      for (int dy = 0; dy < wide.scale; ++dy) {
        const long long y = (first_row + row) * wide.scale + dy;
        for (int dx = 0; dx < wide.scale; ++dx) {
          const long long x = (first_column + column) * wide.scale + dx;
          if (x >= 0 && x < floor_width_px && y >= 0 && y < floor_height_px) sum += floor[y * floor_width_px + x];
        }
      }
      wide_out[row * wide.px + column] = static_cast<std::uint8_t>((2 * sum + n) / (2 * n));  // the mean, halves up
    }
  }
}

}  // namespace scout::render
