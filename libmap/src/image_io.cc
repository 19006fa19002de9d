#include "areomap/map/image_io.h"

#include <OpenImageIO/imageio.h>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {

cv::Mat ReadImage(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path.string() + ": no such file");
  auto input = OIIO::ImageInput::open(path.string());
  if (!input) {
    throw Error(path.string() +
                ": not a readable image (expected PNG, TIFF or JPEG): " + OIIO::geterror());
  }
  const OIIO::ImageSpec& spec = input->spec();
  if (spec.nchannels < 1 || spec.nchannels > 4) {
    throw Error(path.string() + ": has " + std::to_string(spec.nchannels) +
                " channels: expected 1 to 4");
  }
  const bool eight_bit = spec.format == OIIO::TypeDesc::UINT8;
  const OIIO::TypeDesc read_type = eight_bit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16;
  cv::Mat image(spec.height, spec.width, CV_MAKETYPE(eight_bit ? CV_8U : CV_16U, spec.nchannels));
  if (!input->read_image(0, 0, 0, spec.nchannels, read_type, image.data)) {
    throw Error(path.string() + ": read failed (truncated file?): " + input->geterror());
  }
  return image;
}

void WriteImage(const std::filesystem::path& path, const cv::Mat& image) {
  if (image.empty() || image.channels() < 1 || image.channels() > 4 ||
      (image.depth() != CV_8U && image.depth() != CV_16U)) {
    throw Error(path.string() + ": cannot write image: expected 8- or 16-bit with 1-4 channels");
  }
  AtomicFile file(path);
  {
    auto output = OIIO::ImageOutput::create(path.string());
    if (!output) {
      throw Error(path.string() + ": no image writer for this extension: " + OIIO::geterror());
    }
    const OIIO::TypeDesc type =
        image.depth() == CV_8U ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16;
    const OIIO::ImageSpec spec(image.cols, image.rows, image.channels(), type);
    const cv::Mat contiguous = image.isContinuous() ? image : image.clone();
    if (!output->open(file.temp_path().string(), spec) ||
        !output->write_image(type, contiguous.data) || !output->close()) {
      throw Error(path.string() + ": write failed: " + output->geterror());
    }
  }
  file.Commit();
}

}  // namespace areomap
