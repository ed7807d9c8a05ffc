// libpng reading with its setjmp error model kept inside one function that owns no C++ objects
// (a longjmp must not skip destructors): the caller owns the file, the libpng structs and the
// output buffers.
#include "rgbdquad/capture/png_file.h"

#include <png.h>

#include <cstdio>

namespace rgbdquad::capture {
namespace {

enum class Want { kGray16, kRgb8 };

// Owns the FILE and libpng's read structs; releases them on every path.
struct PngReader {
  std::FILE* file = nullptr;
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::string message;  // libpng's error text
  std::vector<png_bytep> rows;
  ~PngReader() {
    if (png != nullptr) png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
    if (file != nullptr) std::fclose(file);
  }
};

void on_error(png_structp png, png_const_charp text) {
  static_cast<PngReader*>(png_get_error_ptr(png))->message = text;
  png_longjmp(png, 1);
}
void on_warning(png_structp, png_const_charp) {}

// Decodes into `bytes` (big-endian samples for 16-bit). Only trivially destructible locals here.
bool decode(PngReader& r, Want want, std::vector<std::uint8_t>& bytes, int* width, int* height) {
  if (setjmp(png_jmpbuf(r.png))) return false;
  png_init_io(r.png, r.file);
  png_read_info(r.png, r.info);
  const png_byte color = png_get_color_type(r.png, r.info);
  const png_byte depth = png_get_bit_depth(r.png, r.info);
  if (want == Want::kGray16) {
    if (color != PNG_COLOR_TYPE_GRAY || depth != 16) {
      r.message = "not a 16-bit grey PNG";
      return false;
    }
  } else {
    if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(r.png);
    if (color == PNG_COLOR_TYPE_GRAY || color == PNG_COLOR_TYPE_GRAY_ALPHA) {
      if (depth < 8) png_set_expand_gray_1_2_4_to_8(r.png);
      png_set_gray_to_rgb(r.png);
    }
    if ((color & PNG_COLOR_MASK_ALPHA) != 0) png_set_strip_alpha(r.png);
    if (depth == 16) png_set_strip_16(r.png);
  }
  png_set_interlace_handling(r.png);
  png_read_update_info(r.png, r.info);
  *width = static_cast<int>(png_get_image_width(r.png, r.info));
  *height = static_cast<int>(png_get_image_height(r.png, r.info));
  const std::size_t row_bytes = png_get_rowbytes(r.png, r.info);
  const std::size_t expected = static_cast<std::size_t>(*width) * (want == Want::kGray16 ? 2 : 3);
  if (row_bytes != expected) {
    r.message = "unexpected row size after conversion";
    return false;
  }
  bytes.resize(row_bytes * static_cast<std::size_t>(*height));
  r.rows.resize(static_cast<std::size_t>(*height));
  for (std::size_t y = 0; y < r.rows.size(); ++y) r.rows[y] = bytes.data() + y * row_bytes;
  png_read_image(r.png, r.rows.data());
  png_read_end(r.png, nullptr);
  return true;
}

bool read(const std::string& path, Want want, std::vector<std::uint8_t>& bytes, int* width,
          int* height, std::string* error) {
  PngReader r;
  r.file = std::fopen(path.c_str(), "rb");
  if (r.file == nullptr) {
    *error = "cannot open " + path;
    return false;
  }
  r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r, on_error, on_warning);
  if (r.png != nullptr) r.info = png_create_info_struct(r.png);
  if (r.png == nullptr || r.info == nullptr) {
    *error = "libpng: out of memory reading " + path;
    return false;
  }
  if (!decode(r, want, bytes, width, height)) {
    *error = path + ": " + r.message;
    return false;
  }
  return true;
}

}  // namespace

std::optional<PngPixels<std::uint16_t>> read_png_gray16(const std::string& path,
                                                        std::string* error) {
  std::vector<std::uint8_t> bytes;
  PngPixels<std::uint16_t> out;
  if (!read(path, Want::kGray16, bytes, &out.width, &out.height, error)) return std::nullopt;
  out.pixels.resize(bytes.size() / 2);
  for (std::size_t i = 0; i < out.pixels.size(); ++i) {  // PNG samples are big-endian
    out.pixels[i] = static_cast<std::uint16_t>((bytes[2 * i] << 8) | bytes[2 * i + 1]);
  }
  return out;
}

std::optional<PngPixels<std::uint8_t>> read_png_rgb8(const std::string& path, std::string* error) {
  PngPixels<std::uint8_t> out;
  if (!read(path, Want::kRgb8, out.pixels, &out.width, &out.height, error)) return std::nullopt;
  return out;
}

}  // namespace rgbdquad::capture
