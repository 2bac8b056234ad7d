// importer.calibration.opencv: the YAML or XML file that OpenCV's calibration
// (cv::calibrateCamera, cv::fisheye::calibrate, and the camera_calibration sample)
// writes through cv::FileStorage:
//   camera_matrix            3x3 [fx 0 cx; 0 fy cy; 0 0 1], pixels, (0,0) = centre of the
//                            top-left pixel (the same convention as strata's)
//   distortion_coefficients  (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tx, ty]]]]), or
//                            for the fisheye model (k1, k2, k3, k4)
//   image_width, image_height
//   fisheye_model: 1, or camera_model / distortion_model: "fisheye" ("equidistant")
#include "importers/calibration/calibration_formats.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <fstream>

#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata::calibration_formats {
namespace {

std::string where(const fs::path& file) { return fmt::format("{}: {}", kOpenCvStage, file.string()); }

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

cv::Mat read_matrix(const cv::FileStorage& storage, const char* key, const fs::path& file, bool required) {
  const cv::FileNode node = storage[key];
  if (node.empty() || node.isNone()) {
    if (required) throw InputError(fmt::format("{}: <{}> is missing", where(file), key));
    return {};
  }
  // OpenCV allocates the matrix its header declares before it reads the data: a
  // header of 2^31 columns asks for 16 GB. The data must hold that many values.
  if (node.isMap()) {
    double declared = 1;  // values, whatever the channels
    const cv::FileNode sizes = node["sizes"];  // an opencv-nd-matrix
    std::vector<cv::FileNode> dims;
    if (sizes.isSeq()) {
      for (auto it = sizes.begin(); it != sizes.end(); ++it) dims.push_back(*it);
    } else {
      dims = {node["rows"], node["cols"]};
    }
    for (const cv::FileNode& d : dims) {
      if (!d.isInt() || int(d) < 0) {
        throw InputError(fmt::format("{}: <{}> has a size that is not a whole number", where(file), key));
      }
      declared *= int(d);
    }
    const cv::FileNode data = node["data"];
    const double held = data.isSeq() ? double(data.size()) : 0;
    if (declared > held) {
      throw InputError(fmt::format("{}: <{}> declares {} values but holds {}", where(file), key, declared, held));
    }
  }
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception& e) {
    throw InputError(fmt::format("{}: <{}> is not a matrix ({})", where(file), key, e.err));
  }
  if (m.empty() || m.channels() != 1) {
    throw InputError(fmt::format("{}: <{}> is not a matrix of numbers", where(file), key));
  }
  m.convertTo(m, CV_64F);
  return m;
}

int read_size(const cv::FileStorage& storage, const char* key, const fs::path& file) {
  const cv::FileNode node = storage[key];
  if (node.empty() || node.isNone()) throw InputError(fmt::format("{}: <{}> is missing", where(file), key));
  if (!node.isInt() || int(node) <= 0) {
    throw InputError(fmt::format("{}: <{}> must be a positive whole number of pixels", where(file), key));
  }
  return int(node);
}

// fisheye_model: 1 (the OpenCV sample), or a model name under one of the usual keys.
bool says_fisheye(const cv::FileStorage& storage) {
  const cv::FileNode flag = storage["fisheye_model"];
  if (flag.isInt() || flag.isReal()) return double(flag) != 0.0;
  for (const char* key : {"camera_model", "distortion_model", "model"}) {
    const cv::FileNode n = storage[key];
    if (n.isString()) {
      const std::string name = lower(std::string(n));
      if (name == "fisheye" || name == "equidistant" || name == "kannala_brandt") return true;
    }
  }
  return false;
}

void read_camera_matrix(const cv::Mat& K, const fs::path& file, Intrinsics& k) {
  if (K.rows != 3 || K.cols != 3) {
    throw InputError(fmt::format("{}: <camera_matrix> is {}x{}; expected 3x3", where(file), K.rows, K.cols));
  }
  if (K.at<double>(0, 1) != 0.0) {
    throw InputError(fmt::format("{}: <camera_matrix> has skew {} (row 1, column 2); strata's camera model "
                                 "has none: recalibrate with zero skew",
                                 where(file), K.at<double>(0, 1)));
  }
  if (K.at<double>(1, 0) != 0.0 || K.at<double>(2, 0) != 0.0 || K.at<double>(2, 1) != 0.0 ||
      K.at<double>(2, 2) != 1.0) {
    throw InputError(fmt::format("{}: <camera_matrix> is not of the form [fx 0 cx; 0 fy cy; 0 0 1]",
                                 where(file)));
  }
  k.fx = K.at<double>(0, 0);
  k.fy = K.at<double>(1, 1);
  k.cx = K.at<double>(0, 2);
  k.cy = K.at<double>(1, 2);
}

void read_distortion(const cv::Mat& D, bool fisheye, const fs::path& file, CalibrationFile& out) {
  Intrinsics& k = out.intrinsics;
  if (D.empty()) {
    k.model = fisheye ? CameraModel::fisheye : CameraModel::radial;
    out.notes.push_back("no <distortion_coefficients>: a lens without distortion");
    return;
  }
  if (D.rows != 1 && D.cols != 1) {
    throw InputError(fmt::format("{}: <distortion_coefficients> is {}x{}; expected one row or column",
                                 where(file), D.rows, D.cols));
  }
  const std::vector<double> d(D.begin<double>(), D.end<double>());
  if (fisheye) {
    if (d.size() != 4) {
      throw InputError(fmt::format("{}: <distortion_coefficients> has {} values; the fisheye model has 4 "
                                   "(k1, k2, k3, k4)",
                                   where(file), d.size()));
    }
    k.model = CameraModel::fisheye;
    k.k1 = d[0];
    k.k2 = d[1];
    k.k3 = d[2];
    k.k4 = d[3];
    return;
  }
  // OpenCV's order: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]].
  if (d.size() != 4 && d.size() != 5 && d.size() != 8 && d.size() != 12 && d.size() != 14) {
    throw InputError(fmt::format("{}: <distortion_coefficients> has {} values; OpenCV writes 4, 5, 8, 12 or "
                                 "14 (or 4 with fisheye_model: 1)",
                                 where(file), d.size()));
  }
  static const char* const kExtra[] = {"k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty"};
  for (std::size_t i = 5; i < d.size(); ++i) {
    if (d[i] != 0.0) {
      throw InputError(fmt::format("{}: <distortion_coefficients> {} = {} (OpenCV's rational, thin-prism or "
                                   "tilt terms) is not in strata's camera models; recalibrate with k1-k3, p1, "
                                   "p2 only",
                                   where(file), kExtra[i - 5], d[i]));
    }
  }
  k.k1 = d[0];
  k.k2 = d[1];
  k.p1 = d[2];
  k.p2 = d[3];
  k.k3 = d.size() >= 5 ? d[4] : 0.0;
  k.model = frame_model_for(k);
}

// OpenCV 4.6's parser puts "<file>(<line>): <what>" in the exception's `func` (and
// only the parser function's name in `err`): made into "stage: file:line: what".
std::string parse_error_message(const fs::path& file, const cv::Exception& e) {
  if (e.code == cv::Error::StsParseError) {
    const std::string& f = e.func;
    const auto open = f.rfind('(', f.find("): "));
    const auto close = f.find("): ");
    if (open != std::string::npos && close != std::string::npos && close > open + 1) {
      return fmt::format("{}:{}: {}", where(file), f.substr(open + 1, close - open - 1), f.substr(close + 3));
    }
    return fmt::format("{}: not a valid OpenCV YAML or XML file: {}", where(file), f);
  }
  return fmt::format("{}: not a valid OpenCV YAML or XML file ({}; OpenCV's YAML starts with '%YAML:1.0')",
                     where(file), e.err);
}

// OpenCV 4.6's XML parser dereferences a null pointer on a NUL byte inside the
// document (corpus/calibration/crash_xml_nul_bytes.xml), and no YAML, XML or JSON
// text holds one: refused before OpenCV sees the file.
void require_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot be read", where(file)));
  char buf[4096];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    if (std::memchr(buf, '\0', std::size_t(in.gcount()))) {
      throw InputError(fmt::format("{}: holds NUL bytes: not a text file (OpenCV's YAML, XML or JSON)",
                                   where(file)));
    }
  }
}

// The reading itself. It runs OpenCV's parser, so read_opencv calls it only on a
// file that require_parse_finishes has seen parsed to the end.
CalibrationFile read_opencv_unguarded(const fs::path& file) {
  cv::FileStorage storage;
  try {
    if (!storage.open(file.string(), cv::FileStorage::READ)) {
      throw InputError(fmt::format("{}: cannot be opened as an OpenCV YAML or XML file", where(file)));
    }
  } catch (const cv::Exception& e) {
    throw InputError(parse_error_message(file, e));
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    // OpenCV 4.6's YAML parser can fail with a standard exception (std::length_error
    // on a mapping key that is empty: corpus/calibration/crash_yaml_empty_key.yml).
    throw InputError(fmt::format("{}: not a valid OpenCV YAML or XML file ({})", where(file), e.what()));
  }
  CalibrationFile out;
  out.format = "opencv";
  Intrinsics& k = out.intrinsics;
  // OpenCV asserts (cv::Exception) where a node is not what it asks for, e.g. a
  // top level that is a list: the same refusal as a file it cannot parse.
  try {
    if (!storage.root().isMap()) {
      throw InputError(fmt::format("{}: the top level is not a map of names (image_width, camera_matrix, ...)",
                                   where(file)));
    }
    k.width = read_size(storage, "image_width", file);
    k.height = read_size(storage, "image_height", file);
    read_camera_matrix(read_matrix(storage, "camera_matrix", file, true), file, k);
    read_distortion(read_matrix(storage, "distortion_coefficients", file, false), says_fisheye(storage), file,
                    out);
  } catch (const cv::Exception& e) {
    throw InputError(fmt::format("{}: not a calibration OpenCV can read ({})", where(file), e.err));
  }
  return out;
}

// A calibration is a few kilobytes of text; a larger file is something else, and
// the size bounds how long a correct parse can take (below).
constexpr std::uintmax_t kMaxCalibrationBytes = 1 << 20;
// OpenCV parses a calibration in about a millisecond; a parse still running after
// this long will not end (seconds of wall time, generous for a loaded machine).
constexpr double kParseTimeLimitS = 3.0;

// OpenCV 4.6's YAML parser never returns on some malformed files
// (corpus/calibration/regression_opencv_yaml_hang.yml) and dereferenced a null
// pointer on others. Which inputs trigger such bugs inside OpenCV cannot be listed
// in advance, so each file is first parsed in a child process with a time limit:
// one that hangs or crashes the child is refused, and the real parse runs only on
// files the child read to the end (parsing is deterministic). A fork costs about a
// millisecond, once per imported calibration.
void require_parse_finishes(const fs::path& file) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) {
    throw IoError(fmt::format("{}: cannot start the checking parser: {}", where(file), std::strerror(errno)));
  }
  const pid_t child = fork();
  if (child < 0) {
    const int err = errno;
    close(pipe_fds[0]);
    close(pipe_fds[1]);
    throw IoError(fmt::format("{}: cannot start the checking parser: {}", where(file), std::strerror(err)));
  }
  if (child == 0) {
    close(pipe_fds[0]);
    try {
      read_opencv_unguarded(file);
    } catch (...) {
      // A refusal is a finished parse; the parent repeats it and reports it.
    }
    const char done = 1;
    if (write(pipe_fds[1], &done, 1) != 1) _exit(2);
    _exit(0);  // no destructors, atexit handlers or leak checks of the parent's state
  }
  close(pipe_fds[1]);
  // The child's end of the pipe closes when it exits, however it exits.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(kParseTimeLimitS);
  bool finished = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    pollfd p{pipe_fds[0], POLLIN, 0};
    const int n = poll(&p, 1, int(left.count()));
    if (n < 0 && errno == EINTR) continue;
    finished = n > 0;
    break;
  }
  if (!finished) kill(child, SIGKILL);
  close(pipe_fds[0]);
  int status = 0;
  while (waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (!finished) {
    throw InputError(fmt::format("{}: OpenCV's parser did not finish reading it within {:.0f} s (a malformed file "
                                 "that hangs OpenCV 4.6); not a calibration strata can read",
                                 where(file), kParseTimeLimitS));
  }
  if (WIFSIGNALED(status)) {
    throw InputError(fmt::format("{}: OpenCV's parser crashed on it (signal {}); not a calibration strata can read",
                                 where(file), WTERMSIG(status)));
  }
}

}  // namespace

CalibrationFile read_opencv(const fs::path& file) {
  require_text(file);
  std::error_code ec;
  const auto bytes = fs::file_size(file, ec);
  if (!ec && bytes > kMaxCalibrationBytes) {
    throw InputError(fmt::format("{}: {} bytes; a calibration file is a few kilobytes of text", where(file), bytes));
  }
  require_parse_finishes(file);
  return read_opencv_unguarded(file);
}

CameraModel frame_model_for(const Intrinsics& k) {
  return (k.k3 == 0.0 && k.p1 == 0.0 && k.p2 == 0.0) ? CameraModel::radial : CameraModel::brown;
}

}  // namespace strata::calibration_formats
