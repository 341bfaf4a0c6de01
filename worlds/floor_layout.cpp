// Floors composed from a data set's images: the layout's rules and the composition itself.
#include "worlds/floor_layout.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <string>

#include "core/random.hpp"

namespace scout::worlds {

namespace {

// "file:line: field: expected ..., got ...", at the field's line, else at the line of `near` (the
// field whose value made the rule apply), else at the section's.
[[noreturn]] void fail(const World& world, const std::string& field, const std::string& expected,
                       const std::string& got, const std::string& near = "") {
  const bool at_near = !world.lines.count(field) && !near.empty() && world.lines.count(near);
  const std::string where = at_near ? fmt::format("{}:{}: {}", world.file.string(), world.lines.at(near), field)
                                    : field_location(world, field);
  throw InputError(one_line(where + ": expected " + expected + ", got " + got));
}

std::string given_or_default(const World& world, const std::string& field, const std::string& value) {
  return value + (world.lines.count(field) ? "" : " (the default)");
}

// The floor is divided into this many cells of at least the image's size, one digit per cell.
struct Cells {
  int columns = 1;
  int rows = 1;
};

Cells digit_cells(int width_px, int height_px, int image_width_px, int image_height_px, int digits) {
  // One digit anywhere on the floor; several each in a cell of their own, so that none overlaps.
  if (digits == 1) return {};
  return {width_px / image_width_px, height_px / image_height_px};
}

int uniform_int(core::Rng& rng, int n) {
  return static_cast<int>(core::uniform_below(rng, static_cast<std::uint64_t>(n)));
}

}  // namespace

void check_layout(const World& world) {
  const FloorSpec& floor = world.floor;
  const bool clutter_px_given = world.lines.count("floor.clutter_px") != 0;
  if (!floor.composed() && floor.clutter == 0 && !clutter_px_given) return;  // a piece size alone: unused
  if (!floor.image.empty()) {
    const std::string field = floor.size_px                          ? "floor.size_px"
                              : floor.layout != FloorLayout::Centred ? "floor.layout"
                              : floor.digits != 1                    ? "floor.digits"
                              : floor.clutter != 0                   ? "floor.clutter"
                                                                     : "floor.clutter_px";
    fail(world, field, "floor.dataset (floors are composed from a data set's digits)", "floor.image");
  }
  if (floor.layout != FloorLayout::Centred && !floor.size_px)
    fail(world, "floor.size_px", fmt::format("[w, h] with layout {}", to_string(floor.layout)), "image",
         "floor.layout");
  if (floor.digits > 1 && floor.layout == FloorLayout::Centred)
    fail(world, "floor.layout", fmt::format("translated or cluttered with digits = {}", floor.digits),
         given_or_default(world, "floor.layout", "centred"), "floor.digits");
  if (floor.layout == FloorLayout::Cluttered && floor.clutter == 0)
    fail(world, "floor.clutter", "at least 1 with layout cluttered", given_or_default(world, "floor.clutter", "0"),
         "floor.layout");
  if (floor.layout != FloorLayout::Cluttered && floor.clutter > 0)
    fail(world, "floor.clutter", fmt::format("0 with layout {}", to_string(floor.layout)),
         std::to_string(floor.clutter));
}

void check_layout(const World& world, int image_width_px, int image_height_px) {
  check_layout(world);
  const FloorSpec& floor = world.floor;
  if (!floor.composed()) return;
  const std::string image = fmt::format("{} x {}", image_width_px, image_height_px);
  const int width = floor.size_px ? floor.size_px->width_px : image_width_px;
  const int height = floor.size_px ? floor.size_px->height_px : image_height_px;
  if (width < image_width_px || height < image_height_px)
    fail(world, "floor.size_px", fmt::format("a floor at least the images' {} pixels", image),
         fmt::format("[{}, {}]", width, height));
  if (floor.layout == FloorLayout::Cluttered) {
    const int smallest = std::min(image_width_px, image_height_px);
    if (floor.clutter_px > smallest)
      fail(world, "floor.clutter_px",
           fmt::format("at most the images' smaller side, {} (they are {} pixels)", smallest, image),
           std::to_string(floor.clutter_px));
  }
  if (floor.digits > 1) {
    const Cells cells = digit_cells(width, height, image_width_px, image_height_px, floor.digits);
    if (cells.columns * cells.rows < floor.digits)
      fail(world, "floor.digits",
           fmt::format("at most {} (a [{}, {}] floor holds {} x {} cells of the images' {} pixels, one digit each)",
                       cells.columns * cells.rows, width, height, cells.columns, cells.rows, image),
           std::to_string(floor.digits));
  }
}

FloorComposer::FloorComposer(int image_width_px, int image_height_px)
    : image_width_px_(image_width_px),
      image_height_px_(image_height_px),
      width_px_(image_width_px),
      height_px_(image_height_px) {}

FloorComposer::FloorComposer(const World& world, int image_width_px, int image_height_px)
    : FloorComposer(image_width_px, image_height_px) {
  check_layout(world, image_width_px, image_height_px);
  spec_ = world.floor;
  if (spec_.size_px) {
    width_px_ = spec_.size_px->width_px;
    height_px_ = spec_.size_px->height_px;
  }
  copies_ = width_px_ == image_width_px && height_px_ == image_height_px && spec_.layout == FloorLayout::Centred &&
            spec_.digits == 1;
}

FloorPlan FloorComposer::plan(int index, int image_count, std::uint64_t key) const {
  FloorPlan p;
  p.digit_count = spec_.digits;
  if (copies_) {
    p.digits[0] = {index, 0, 0};
    return p;
  }
  const int w = image_width_px_, h = image_height_px_;
  if (spec_.layout == FloorLayout::Centred) {
    p.digits[0] = {index, (width_px_ - w) / 2, (height_px_ - h) / 2};
    return p;
  }
  core::Rng rng(core::derive_seed(key, static_cast<std::uint64_t>(index)));
  // The digits: the floor's own first, then others of the split; each in its own cell.
  const Cells cells = digit_cells(width_px_, height_px_, w, h, spec_.digits);
  const int cell_w = width_px_ / cells.columns, cell_h = height_px_ / cells.rows;
  std::array<int, kMaxFloorDigits> cell_of{};
  int chosen = 0;
  while (chosen < spec_.digits) {  // distinct cells, drawn without replacement
    const int c = uniform_int(rng, cells.columns * cells.rows);
    if (std::find(cell_of.begin(), cell_of.begin() + chosen, c) == cell_of.begin() + chosen) cell_of[chosen++] = c;
  }
  for (int d = 0; d < spec_.digits; ++d) {
    const int image = d == 0 || image_count < 2 ? index : uniform_int(rng, image_count);
    const int cx = cell_of[d] % cells.columns * cell_w, cy = cell_of[d] / cells.columns * cell_h;
    p.digits[d] = {image, cx + uniform_int(rng, cell_w - w + 1), cy + uniform_int(rng, cell_h - h + 1)};
  }
  // Clutter: a piece of another image of the split, anywhere on the floor.
  const int piece = spec_.clutter_px;
  p.clutter.resize(spec_.layout == FloorLayout::Cluttered ? spec_.clutter : 0);
  for (FloorPlan::Piece& c : p.clutter) {
    c.image = uniform_int(rng, image_count);
    if (image_count > 1 && c.image == index) c.image = (c.image + 1) % image_count;
    c.from_x = uniform_int(rng, w - piece + 1);
    c.from_y = uniform_int(rng, h - piece + 1);
    c.x = uniform_int(rng, width_px_ - piece + 1);
    c.y = uniform_int(rng, height_px_ - piece + 1);
  }
  return p;
}

void FloorComposer::paint(const FloorPlan& plan, const ImageSet& images, std::span<std::uint8_t> out) const {
  const std::size_t area = static_cast<std::size_t>(width_px_) * height_px_;
  if (out.size() != area || images.cols != image_width_px_ || images.rows != image_height_px_)
    throw std::invalid_argument("FloorComposer::paint: floor or image size differs from the composer's");
  if (copies_) {
    std::copy_n(images.image(plan.digits[0].image), area, out.data());
    return;
  }
  std::fill(out.begin(), out.end(), std::uint8_t{0});
  // Copies the w x h window at (from_x, from_y) of `image` to (x, y) on the floor, brightest wins.
  const auto blit = [&](int image, int from_x, int from_y, int w, int h, int x, int y) {
    const std::uint8_t* source = images.image(image);
    for (int r = 0; r < h; ++r) {
      const std::uint8_t* row = source + static_cast<std::size_t>(from_y + r) * image_width_px_ + from_x;
      std::uint8_t* to = out.data() + static_cast<std::size_t>(y + r) * width_px_ + x;
      for (int c = 0; c < w; ++c) to[c] = std::max(to[c], row[c]);
    }
  };
  for (const FloorPlan::Piece& c : plan.clutter)
    blit(c.image, c.from_x, c.from_y, spec_.clutter_px, spec_.clutter_px, c.x, c.y);
  for (int d = 0; d < plan.digit_count; ++d)
    blit(plan.digits[d].image, 0, 0, image_width_px_, image_height_px_, plan.digits[d].x, plan.digits[d].y);
}

}  // namespace scout::worlds
