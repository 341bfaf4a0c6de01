#include <opencv2/core/version.hpp>

#include "render/snapshot.hpp"

namespace scout::render {

std::string image_library_version() { return "OpenCV " CV_VERSION; }

}  // namespace scout::render
