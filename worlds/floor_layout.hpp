#pragma once
/// Floors larger than the digit (worlds/README.md § Floors larger than the digit): a floor of
/// `floor.size_px` composed from a data set's images by `floor.layout`: the digit centred, at a
/// random place (translated), among pieces of other digits (cluttered), or several digits, each in
/// its own cell of the floor, labelled by their sum.
///
/// Composition is a pure function of (image index, key, the split's image count): the same data,
/// world and key give the same floor on every machine. (Clutter and partner digits are drawn from
/// the whole set given, so a set cut short, `--limit`, composes other floors than the whole one.) Callers choose the
/// key: a training epoch's, a run's, an evaluation's (learn/ and env/ say which), so that a digit lands elsewhere on
/// every draw.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "worlds/dataset.hpp"
#include "worlds/idx.hpp"
#include "worlds/world.hpp"

namespace scout::worlds {

/// The most clutter pieces on one floor (the schema's bound on floor.clutter).
inline constexpr int kMaxClutterPieces = 1000;

/// Where everything of one floor goes: the digits (image indices, top-left corners on the floor)
/// and the clutter pieces (source image, the piece's corner in it, its corner on the floor).
struct FloorPlan {
  struct Digit {
    int image = 0;
    int x = 0;
    int y = 0;
  };
  struct Piece {
    int image = 0;
    int from_x = 0;
    int from_y = 0;
    int x = 0;
    int y = 0;
  };
  std::array<Digit, kMaxFloorDigits> digits{};
  int digit_count = 0;
  std::vector<Piece> clutter;
};

/// Composes the floors of one world from images of one size.
class FloorComposer {
 public:
  /// Today's floors: floor i is image i of `image_width_px` x `image_height_px`.
  FloorComposer(int image_width_px, int image_height_px);
  /// The floors of `spec` (checked by check_layout against the image size; throws InputError
  /// naming the world's field where it does not fit).
  FloorComposer(const World& world, int image_width_px, int image_height_px);

  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  int image_width_px() const { return image_width_px_; }
  int image_height_px() const { return image_height_px_; }
  int digits() const { return spec_.digits; }
  /// True when floor i is image i itself (no composition, no randomness).
  bool copies_images() const { return copies_; }

  /// Where floor `index` of a split of `image_count` images puts its digits and clutter under `key`.
  /// Other digits and clutter come from other images of the same split.
  FloorPlan plan(int index, int image_count, std::uint64_t key) const;
  /// Paints `plan` from `images` into `out` (width_px() * height_px() bytes): black, then the
  /// clutter, then the digits, each pixel the brightest of what lands on it.
  void paint(const FloorPlan& plan, const ImageSet& images, std::span<std::uint8_t> out) const;

  /// plan() then paint(); returns the floor's label (the sum of its digits' labels).
  template <class Label>
  int compose(const ImageSet& images, const std::vector<Label>& labels, int index, std::uint64_t key,
              std::span<std::uint8_t> out) const {
    const FloorPlan p = plan(index, images.count, key);
    paint(p, images, out);
    return label(p, labels);
  }

  /// The label of floor `index` under `key`, without painting it.
  template <class Label>
  int label(const std::vector<Label>& labels, int index, std::uint64_t key) const {
    if (copies_) return static_cast<int>(labels[index]);
    return label(plan(index, static_cast<int>(labels.size()), key), labels);
  }

  /// The number of classes of floors whose images have `image_classes` classes (0 .. D - 1):
  /// D itself with one digit, (D - 1) * n + 1 sums with n.
  int classes(int image_classes) const { return (image_classes - 1) * spec_.digits + 1; }

 private:
  template <class Label>
  static int label(const FloorPlan& p, const std::vector<Label>& labels) {
    int sum = 0;
    for (int d = 0; d < p.digit_count; ++d) sum += static_cast<int>(labels[p.digits[d].image]);
    return sum;
  }

  FloorSpec spec_;
  int image_width_px_ = 0;
  int image_height_px_ = 0;
  int width_px_ = 0;
  int height_px_ = 0;
  bool copies_ = true;
};

/// A split's labelled images and the floors a layout makes of them under one key (a training
/// epoch's, an evaluation's): floor i is composed from image i (and, for several digits or
/// clutter, from others of the split).
struct FloorSource {
  const LabeledImages* images = nullptr;
  FloorComposer composer{0, 0};
  std::uint64_t key = 0;

  /// Today's floors: the images themselves.
  static FloorSource of_images(const LabeledImages& images) {
    return {&images, FloorComposer(images.images.cols, images.images.rows), 0};
  }
  int count() const { return images->images.count; }
  int width_px() const { return composer.width_px(); }
  int height_px() const { return composer.height_px(); }
  /// Floor `index` into `out` (width * height bytes); returns its label.
  int floor(int index, std::span<std::uint8_t> out) const {
    return composer.compose(images->images, images->labels, index, key, out);
  }
  int label(int index) const { return composer.label(images->labels, index, key); }
  /// Floors first .. first + n - 1 into `out` (n * width * height bytes).
  void floors(int first, int n, std::span<std::uint8_t> out) const {
    const std::size_t area = static_cast<std::size_t>(width_px()) * height_px();
    for (int i = 0; i < n; ++i) floor(first + i, out.subspan(area * i, area));
  }
};

/// The layout's rules that need no image (called by the world loader): a size for a composed
/// layout, clutter only when cluttered, several digits only off the centre, a data set, not a
/// PNG. Throws InputError "file:line: floor.<field>: expected ..., got ...".
void check_layout(const World& world);

/// The layout's rules against the data set's image size: a floor at least the image, clutter
/// pieces within the image and the floor, the digits' cells on the floor. Throws InputError.
void check_layout(const World& world, int image_width_px, int image_height_px);

}  // namespace scout::worlds
