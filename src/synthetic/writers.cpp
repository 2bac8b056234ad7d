#include "synthetic/writers.hpp"

#include "core/error.hpp"

#include <exiv2/exiv2.hpp>
#include <opencv2/imgcodecs.hpp>

#include <bit>
#include <cmath>
#include <mutex>

namespace strata::synthetic {

void write_jpeg(const std::filesystem::path& path, const std::vector<std::uint8_t>& rgb, int width,
                int height, int quality, const ExifFields& e) {
  cv::Mat bgr(height, width, CV_8UC3);
  for (int v = 0; v < height; ++v) {
    auto* row = bgr.ptr<std::uint8_t>(v);
    const std::uint8_t* src = rgb.data() + 3 * std::size_t(v) * std::size_t(width);
    for (int u = 0; u < width; ++u) {
      row[3 * u] = src[3 * u + 2];
      row[3 * u + 1] = src[3 * u + 1];
      row[3 * u + 2] = src[3 * u];
    }
  }
  std::vector<std::uint8_t> jpeg;
  if (!cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, quality}))
    throw IoError("synth.writer.jpeg: cannot encode " + path.string());

  if (!e.write) {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(jpeg.data()), std::streamsize(jpeg.size()));
    out.close();
    if (!out) throw IoError("synth.writer.jpeg: cannot write " + path.string());
    return;
  }
  // exiv2 0.27 is not reliably thread-safe: one image at a time.
  static std::mutex exiv2_mutex;
  std::lock_guard lock(exiv2_mutex);
  try {
    auto image = Exiv2::ImageFactory::open(jpeg.data(), long(jpeg.size()));
    Exiv2::ExifData exif;
    exif["Exif.Image.Make"] = e.make;
    exif["Exif.Image.Model"] = e.model;
    exif["Exif.Image.Software"] = e.software;
    exif["Exif.Image.ImageDescription"] = e.description;
    exif["Exif.Image.Orientation"] = std::uint16_t(1);
    exif["Exif.Image.DateTime"] = e.datetime;
    exif["Exif.Photo.DateTimeOriginal"] = e.datetime;
    exif["Exif.Photo.DateTimeDigitized"] = e.datetime;
    exif["Exif.Photo.FocalLength"] = Exiv2::URational(std::uint32_t(std::lround(e.focal_mm * 100)), 100);
    exif["Exif.Photo.FocalLengthIn35mmFilm"] = std::uint16_t(e.focal_35mm);
    exif["Exif.Photo.PixelXDimension"] = std::uint32_t(e.width);
    exif["Exif.Photo.PixelYDimension"] = std::uint32_t(e.height);
    // Pixels per centimetre of sensor (unit 3 = cm): lets readers recover the sensor width.
    exif["Exif.Photo.FocalPlaneXResolution"] =
        Exiv2::URational(std::uint32_t(std::lround(e.width / (e.sensor_width_mm / 10.0) * 1000)), 1000);
    exif["Exif.Photo.FocalPlaneYResolution"] =
        Exiv2::URational(std::uint32_t(std::lround(e.width / (e.sensor_width_mm / 10.0) * 1000)), 1000);
    exif["Exif.Photo.FocalPlaneResolutionUnit"] = std::uint16_t(3);
    exif["Exif.Photo.ExposureTime"] = Exiv2::URational(1, 250);
    exif["Exif.Photo.FNumber"] = Exiv2::URational(8, 1);
    exif["Exif.Photo.ISOSpeedRatings"] = std::uint16_t(200);
    image->setExifData(exif);
    image->writeMetadata();
    Exiv2::BasicIo& io = image->io();
    io.seek(0, Exiv2::BasicIo::beg);
    const long size = io.size();
    Exiv2::DataBuf buf = io.read(size);
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(buf.pData_), buf.size_);
    out.close();
    if (!out) throw IoError("synth.writer.jpeg: cannot write " + path.string());
  } catch (const Exiv2::AnyError& err) {
    throw IoError("synth.writer.jpeg: " + path.string() + ": EXIF: " + err.what());
  }
}

void write_scan_ply(const std::filesystem::path& path, const std::vector<Eigen::Vector3f>& points,
                    const std::vector<float>& intensity, const std::string& comment) {
  static_assert(std::endian::native == std::endian::little, "the PLY is written little-endian as in memory");
  if (points.size() != intensity.size()) throw IoError("synth.writer.ply: " + path.string() + ": ragged point data");
  std::ofstream out(path, std::ios::binary);
  if (!out) throw IoError("synth.writer.ply: cannot create " + path.string());
  out << "ply\nformat binary_little_endian 1.0\ncomment " << comment << "\nelement vertex " << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n";
  std::vector<float> record(4 * points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    record[4 * i] = points[i].x();
    record[4 * i + 1] = points[i].y();
    record[4 * i + 2] = points[i].z();
    record[4 * i + 3] = intensity[i];
  }
  out.write(reinterpret_cast<const char*>(record.data()), std::streamsize(record.size() * sizeof(float)));
  out.close();
  if (!out) throw IoError("synth.writer.ply: cannot write " + path.string());
}

TextFile::TextFile(const std::filesystem::path& path) : path_(path), out_(path, std::ios::binary) {
  if (!out_) throw IoError("synth.writer: cannot create " + path.string());
}

void TextFile::close() {
  out_.close();
  if (!out_) throw IoError("synth.writer: cannot write " + path_.string());
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

}  // namespace strata::synthetic
