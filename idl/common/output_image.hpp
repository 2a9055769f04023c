// An image written under output_file.hpp's rule: encoded in memory in the format its file's
// extension names, then written as any other output. Header only, so that cell_common itself
// does not link OpenCV: the programs that write images have it already.
#pragma once

#include <opencv2/core/mat.hpp>
#include <opencv2/imgcodecs.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "common/output_file.hpp"

namespace common {

// Writes `bgr` (OpenCV's channel order) as `file`. Throws FileError, one line naming the file.
inline void write_output_image(const std::filesystem::path& file, const cv::Mat& bgr) {
  check_output_file(file, "image");  // the name first: "/" is no image's name, whatever its extension
  std::vector<unsigned char> bytes;
  bool encoded = false;
  try {
    encoded = cv::imencode(file.extension().string(), bgr, bytes);
  } catch (const cv::Exception&) {
    encoded = false;  // an extension OpenCV has no encoder for: said below, in one line
  }
  if (!encoded)
    throw FileError(file.string() + ": cannot encode an image as '" + file.extension().string() +
                    "' (name it .png, .jpg, .ppm or .bmp)");
  write_output_file(file, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), "image");
}

}  // namespace common
