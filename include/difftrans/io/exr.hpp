// OpenEXR images, linear float RGB (half or float channels in, float out),
// through the OpenEXR library.
#pragma once

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>

#include <exception>
#include <string>

#include "difftrans/io/image.hpp"

namespace difftrans::io {

// Reads R, G, B (or Y, repeated as grey) of an EXR file's data window.
inline Image read_exr(const std::filesystem::path& path) {
  detail::require_readable(path);
  Image image;
  try {
    Imf::InputFile file(path.string().c_str());
    const Imath::Box2i window = file.header().dataWindow();
    const long w = long(window.max.x) - window.min.x + 1, h = long(window.max.y) - window.min.y + 1;
    if (w <= 0 || h <= 0 || w * h > max_file_image_pixels)
      throw Error(path, "data window of " + std::to_string(w) + " x " + std::to_string(h) +
                            " pixels is empty or beyond the limit of " + std::to_string(max_file_image_pixels) +
                            " pixels");
    // every block of scanlines must be in the file before its pixels are allocated (a
    // truncated file, or a data window larger than the file can hold, is refused here)
    if (!file.isComplete())
      throw Error(path, "truncated: the file does not hold every scanline block of its " + std::to_string(w) + " x " +
                            std::to_string(h) + " data window");
    const Imf::ChannelList& channels = file.header().channels();
    const char* names[3] = {"R", "G", "B"};
    bool rgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    if (!rgb && !channels.findChannel("Y"))
      throw Error(path, "no R, G, B (or Y) channels");
    image = Image(int(w), int(h));
    Imf::FrameBuffer buffer;
    // The slice base is addressed with absolute data-window coordinates.
    char* base = reinterpret_cast<char*>(image.rgb.data()) -
                 (std::ptrdiff_t(window.min.x) + std::ptrdiff_t(window.min.y) * w) * std::ptrdiff_t(3 * sizeof(float));
    // Grey (Y only) is read into R and copied to G and B below.
    for (int c = 0; c < (rgb ? 3 : 1); ++c)
      buffer.insert(rgb ? names[c] : "Y",
                    Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float), size_t(w) * 3 * sizeof(float),
                               1, 1, 0.0));
    file.setFrameBuffer(buffer);
    file.readPixels(window.min.y, window.max.y);
    if (!rgb)
      for (size_t p = 0; p < image.pixel_count(); ++p) image.rgb[p * 3 + 1] = image.rgb[p * 3 + 2] = image.rgb[p * 3];
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path, std::string("cannot read EXR: ") + e.what());
  }
  check_finite(image, path);
  return image;
}

// Writes 32-bit float R, G, B with ZIP compression (lossless round trip).
inline void write_exr(const std::filesystem::path& path, const Image& image) {
  check_shape(image, path);
  check_finite(image, path);
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    const char* names[3] = {"R", "G", "B"};
    Imf::FrameBuffer buffer;
    char* base = const_cast<char*>(reinterpret_cast<const char*>(image.rgb.data()));
    for (int c = 0; c < 3; ++c) {
      header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
      buffer.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float),
                                         size_t(image.width) * 3 * sizeof(float)));
    }
    Imf::OutputFile file(path.string().c_str(), header);
    file.setFrameBuffer(buffer);
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    throw Error(path, std::string("cannot write EXR: ") + e.what());
  }
}

}  // namespace difftrans::io
