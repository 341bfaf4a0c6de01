#include "worlds/floors.hpp"

#include <opencv2/imgcodecs.hpp>

#include "worlds/dataset.hpp"

namespace scout::worlds {

namespace {

std::string at_line(const World& world, const std::string& field) {
  const auto it = world.lines.find(field);
  const std::string file = world.file.string();
  return it == world.lines.end() ? file + ": " + field : file + ":" + std::to_string(it->second) + ": " + field;
}

FloorSet load_png(const World& world) {
  const std::filesystem::path& file = world.floor.image;
  if (!std::filesystem::is_regular_file(file))
    throw InputError(at_line(world, "floor.image") + ": expected a PNG file, got '" + file.string() + "' (no such file)");
  cv::Mat gray;
  try {
    gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception&) {
    gray.release();
  }
  if (gray.empty() || gray.type() != CV_8UC1)
    throw InputError(at_line(world, "floor.image") + ": expected a readable PNG image, got '" + file.string() + "'");
  FloorSet set;
  set.images.count = 1;
  set.images.rows = gray.rows;
  set.images.cols = gray.cols;
  set.images.pixels.resize(static_cast<std::size_t>(gray.rows) * gray.cols);
  for (int r = 0; r < gray.rows; ++r)
    std::copy_n(gray.ptr<std::uint8_t>(r), gray.cols, set.images.pixels.data() + static_cast<std::size_t>(r) * gray.cols);
  set.labels = {-1};
  set.source = file.string();
  set.files = {file};
  return set;
}

FloorSet load_dataset(const World& world, const std::filesystem::path& data_root) {
  const std::filesystem::path folder = dataset_folder(world.floor.dataset, data_root);
  LabeledImages data = load_split(folder, world.floor.split);
  FloorSet set;
  set.images = std::move(data.images);
  set.labels.assign(data.labels.begin(), data.labels.end());
  set.source = world.floor.dataset;
  set.split = world.floor.split;
  set.files = std::move(data.files);
  if (set.images.count == 0)
    throw InputError(at_line(world, "floor.split") + ": expected a split with images, got an empty one in " + folder.string());
  if (world.floor.index && *world.floor.index >= set.images.count)
    throw InputError(at_line(world, "floor.index") + ": expected an index in [0, " + std::to_string(set.images.count - 1) +
                     "] or random, got " + std::to_string(*world.floor.index));
  return set;
}

}  // namespace

FloorSet load_floors(const World& world, const std::filesystem::path& data_root) {
  FloorSet set = world.floor.image.empty() ? load_dataset(world, data_root) : load_png(world);
  check_against_floor(world, set.width_px(), set.height_px());
  return set;
}

}  // namespace scout::worlds
