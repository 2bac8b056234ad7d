#include "pipeline/lens_setup.hpp"

#include "core/error.hpp"
#include "core/log.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

namespace strata {
namespace {

// Words that name a fisheye lens or a camera that only has one (action cameras), in
// a camera's EXIF make or model, compared in lower case.
constexpr const char* kFisheyeWords[] = {"fisheye", "fish-eye", "fish eye", "gopro", "insta360"};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

std::optional<std::string> fisheye_word(const CameraRecord& camera) {
  const std::string text = lower(camera.make + " " + camera.model);
  for (const char* w : kFisheyeWords) {
    if (text.find(w) != std::string::npos) return std::string(w);
  }
  return std::nullopt;
}

bool searched(const CameraGroup& g) { return !g.focal_from_exif && !g.calibration_known; }

// Attempt a beats attempt b: more photos registered, then a lower RMSE.
bool better(const FocalAttempt& a, const FocalAttempt& b) {
  if (a.registered != b.registered) return a.registered > b.registered;
  return a.rmse_px < b.rmse_px;
}

}  // namespace

void LensChoiceOptions::validate() const {
  if (model != "auto" && !camera_model_from_string(model)) {
    throw InputError(fmt::format(
        "camera model: option model must be auto, radial, brown or fisheye (got '{}')", model));
  }
  if (!(fisheye_below_35mm > 0) || !(brown_below_35mm >= fisheye_below_35mm)) {
    throw InputError(fmt::format(
        "camera model: options fisheye_below_35mm ({}) and brown_below_35mm ({}) must be > 0 "
        "and in increasing order", fisheye_below_35mm, brown_below_35mm));
  }
}

std::optional<double> equivalent_focal_35mm(const CameraRecord& camera) {
  if (camera.focal_35mm && *camera.focal_35mm > 0) return *camera.focal_35mm;
  if (camera.focal_px && *camera.focal_px > 0 && camera.width > 0) {
    return *camera.focal_px / double(std::max(camera.width, camera.height)) * 36.0;
  }
  return std::nullopt;
}

LensChoice choose_lens_model(const LensChoiceOptions& options,
                             const std::optional<CameraRecord>& camera) {
  LensChoice c;
  if (camera) c.focal_35mm = equivalent_focal_35mm(*camera);
  if (options.model != "auto") {
    c.model = *camera_model_from_string(options.model);
    c.source = "option";
    c.reason = fmt::format("{} as asked (--camera-model)", options.model);
    return c;
  }
  if (camera) {
    if (const auto word = fisheye_word(*camera)) {
      c.model = CameraModel::fisheye;
      c.source = "lens_name";
      c.reason = fmt::format("fisheye: '{}' in the camera name '{} {}'", *word, camera->make,
                             camera->model);
      return c;
    }
  }
  if (!c.focal_35mm) {
    c.model = CameraModel::radial;
    c.source = "default";
    c.reason = "radial: no focal length in the EXIF, nothing known about the lens";
    return c;
  }
  const double f35 = *c.focal_35mm;
  c.source = "focal_35mm";
  if (f35 < options.fisheye_below_35mm) {
    c.model = CameraModel::fisheye;
    c.reason = fmt::format("fisheye: {:.1f} mm equivalent focal, below {:.0f} mm", f35,
                           options.fisheye_below_35mm);
  } else if (f35 < options.brown_below_35mm) {
    c.model = CameraModel::brown;
    c.reason = fmt::format("brown: {:.1f} mm equivalent focal, a wide lens (below {:.0f} mm)", f35,
                           options.brown_below_35mm);
  } else {
    c.model = CameraModel::radial;
    c.reason = fmt::format("radial: {:.1f} mm equivalent focal, {:.0f} mm or longer", f35,
                           options.brown_below_35mm);
  }
  return c;
}

void apply_lens_choice(CameraGroup& group, LensChoice& choice) {
  if (group.calibration_known) {
    choice.model = group.intrinsics.model;
    choice.source = "calibration";
    choice.reason = fmt::format("{}: the known calibration's model ({})", to_string(choice.model),
                                group.calibration_source);
    return;
  }
  group.intrinsics.model = choice.model;
}

void FocalSearchOptions::validate() const {
  if (factors.empty()) throw InputError("focal search: option factors must not be empty");
  for (double f : factors) {
    if (!(f > 0.1 && f < 20)) {
      throw InputError(fmt::format("focal search: option factors: {} is not in (0.1, 20)", f));
    }
  }
  if (!(min_registered_fraction >= 0 && min_registered_fraction <= 1)) {
    throw InputError(fmt::format("focal search: option min_registered_fraction must be in [0, 1] "
                                 "(got {})", min_registered_fraction));
  }
  if (!(max_rmse_px > 0)) {
    throw InputError(fmt::format("focal search: option max_rmse_px must be > 0 (got {})", max_rmse_px));
  }
}

Reconstruction reconstruct_with_focal_search(const FocalSearchOptions& options,
                                             const std::vector<CameraGroup>& groups,
                                             const ReconstructFunction& reconstruct,
                                             IncrementalSummary& best_summary,
                                             FocalSearchSummary& summary) {
  summary = {};
  for (int g = 0; g < int(groups.size()); ++g) {
    if (searched(groups[g])) summary.groups.push_back(g);
  }
  const std::size_t n_attempts =
      options.enabled && !summary.groups.empty() ? options.factors.size() : 1;

  std::optional<Reconstruction> best;
  int best_index = -1;
  std::optional<ProcessingError> first_error;
  for (std::size_t a = 0; a < n_attempts; ++a) {
    FocalAttempt attempt;
    std::vector<CameraGroup> start = groups;
    if (!summary.groups.empty()) {
      attempt.factor = options.factors[a];
      for (int g : summary.groups) {
        Intrinsics& k = start[g].intrinsics;
        k.fx = k.fy = attempt.factor * std::max(k.width, k.height);
        k.cx = 0.5 * (k.width - 1);  // (0,0) is the centre of the top-left pixel
        k.cy = 0.5 * (k.height - 1);
        attempt.prior_px.push_back(k.fx);
      }
    }
    IncrementalSummary is;
    try {
      Reconstruction rec = reconstruct(start, is);
      attempt.registered = is.registered;
      attempt.rmse_px = is.reprojection_rmse_px;
      for (int g : summary.groups) attempt.focal_px.push_back(rec.groups[g].intrinsics.fx);
      const bool beats = !best || better(attempt, summary.attempts[best_index]);
      summary.attempts.push_back(attempt);
      if (beats) {
        best = std::move(rec);
        best_summary = is;
        best_index = int(summary.attempts.size()) - 1;
      }
    } catch (const ProcessingError& e) {
      attempt.rmse_px = std::numeric_limits<double>::infinity();
      attempt.failure = e.what();
      summary.attempts.push_back(attempt);
      if (!first_error) first_error = e;
    }
    const auto& last = summary.attempts.back();
    if (!summary.groups.empty()) {
      log::info("focal search: prior {:.1f} x long side ({:.0f} px): {}", attempt.factor,
                attempt.prior_px.empty() ? 0.0 : attempt.prior_px.front(),
                last.failure.empty()
                    ? fmt::format("{} / {} photos, RMSE {:.3f} px, focal {:.0f} px", last.registered,
                                  is.images, last.rmse_px, last.focal_px.front())
                    : "failed: " + last.failure);
    }
    // The first attempt (the default prior) is kept when it is good enough.
    if (a == 0 && best && double(best_summary.registered) >=
                              options.min_registered_fraction * double(best_summary.images) &&
        best_summary.reprojection_rmse_px <= options.max_rmse_px) {
      break;
    }
  }
  if (!best) throw *first_error;
  summary.attempts[best_index].chosen = true;
  if (summary.attempts.size() > 1) {
    log::info("focal search: kept the prior {:.1f} x long side ({} photos, RMSE {:.3f} px)",
              summary.attempts[best_index].factor, summary.attempts[best_index].registered,
              summary.attempts[best_index].rmse_px);
  }
  return std::move(*best);
}

}  // namespace strata
