#pragma once
// reader.point_cloud: the points of a range scan (terrestrial laser scanner, phone
// LiDAR) from PLY, PTS, XYZ/TXT or LAS, in the file's own frame. The format is told by
// the file's first bytes (PLY, LAS, E57) and then by its extension (.pts, .xyz, .txt,
// .asc, .csv). Read in chunks, so a caller that only needs figures (the importer's
// count and bounding box) holds one chunk at a time, never the whole cloud.
// Every error is an InputError (IoError when the file cannot be opened) starting with
// the reader's stage name (importer.scans.ply, .pts, .xyz, .las) and the file, and
// naming the line, point or byte at fault.
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace strata {

using Rgb8 = std::array<std::uint8_t, 3>;

// Points in the file's frame (metres as the file has them). The attribute vectors
// are empty when the file has no such attribute, else one entry per position.
struct PointCloud {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Rgb8> colours;        // 8 bits per channel (LAS's 16-bit colour: high byte)
  std::vector<float> intensities;   // as stored in the file, not rescaled
  std::vector<Eigen::Vector3f> normals;

  std::size_t size() const { return positions.size(); }
  void clear();
};

// What a whole file holds, known once it has been read through.
struct PointCloudInfo {
  std::string format;           // e.g. "ply binary_little_endian", "las 1.4 point format 6", "pts", "xyz"
  std::uint64_t points = 0;
  bool has_colour = false;
  bool has_intensity = false;
  bool has_normals = false;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();  // bounding box, file's frame
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

// Called with each chunk of consecutive points (at most ReadOptions::chunk_points),
// in file order. `first_index` is the 0-based index of the chunk's first point.
using PointChunkSink = std::function<void(const PointCloud& chunk, std::uint64_t first_index)>;

struct ReadOptions {
  std::size_t chunk_points = 1 << 16;  // points per chunk handed to the sink; > 0
};

// Reads every point, handing them over in chunks; refuses (InputError) a wrong or
// unknown header, a file with fewer points than it declares, a NaN or infinite
// coordinate and a file with no point at all. E57 and LAZ are refused with what to
// convert them to: no Debian 12 package provides a library for them.
PointCloudInfo read_point_cloud_chunks(const std::filesystem::path& file, const PointChunkSink& sink,
                                       const ReadOptions& options = {});

// The whole cloud in memory (for stages that need every point at once).
PointCloud read_point_cloud(const std::filesystem::path& file, PointCloudInfo* info = nullptr);

}  // namespace strata
