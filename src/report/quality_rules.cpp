#include "report/quality_rules.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

std::string list_names(const std::vector<std::string>& names, std::size_t max_listed = 6) {
  std::string s;
  for (std::size_t i = 0; i < names.size() && i < max_listed; ++i) s += (i ? ", " : "") + names[i];
  if (names.size() > max_listed) s += fmt::format(" and {} more", names.size() - max_listed);
  return s;
}

std::string photos_word(int n) { return n == 1 ? "photo" : "photos"; }

}  // namespace

void QualityThresholds::validate() const {
  auto require = [](bool ok, const char* field) {
    if (!ok) throw InputError(fmt::format("report thresholds: {} is out of range", field));
  };
  require(min_photos >= 1, "min_photos");
  require(min_photos_per_area >= 1, "min_photos_per_area");
  require(min_shortfall_fraction > 0 && min_shortfall_fraction <= 1, "min_shortfall_fraction");
  require(max_gsd_m > 0, "max_gsd_m");
  require(min_marker_photos >= 2, "min_marker_photos");
  require(min_control_markers >= 3, "min_control_markers");
  require(max_control_rmse_m > 0, "max_control_rmse_m");
  require(max_check_rmse_m > 0, "max_check_rmse_m");
  require(max_marker_residual_m > 0, "max_marker_residual_m");
  require(max_reprojection_rmse_px > 0, "max_reprojection_rmse_px");
  require(max_unaligned_fraction >= 0 && max_unaligned_fraction <= 1, "max_unaligned_fraction");
  require(survey_allowance >= 1, "survey_allowance");
}

const char* to_string(Severity s) {
  switch (s) {
    case Severity::problem:
      return "problem";
    case Severity::warning:
      return "warning";
    case Severity::note:
      return "note";
  }
  return "note";
}

namespace {
std::vector<Finding> evaluate_unsorted(const LayerFigures& f, const QualityThresholds& t);
}  // namespace

double expected_marker_error_m(const Eigen::Vector3d& stated_sigma_m, double plan_rounding_sigma_m,
                               double height_rounding_sigma_m, double photo_sigma_m) {
  const Eigen::Vector3d rounding(plan_rounding_sigma_m, plan_rounding_sigma_m, height_rounding_sigma_m);
  const Eigen::Vector3d survey = stated_sigma_m.cwiseMax(rounding);
  return std::sqrt(survey.squaredNorm() + photo_sigma_m * photo_sigma_m);
}

double allowed_marker_residual_m(const MarkerFigures& m, const QualityThresholds& t) {
  return std::max(t.max_marker_residual_m, t.survey_allowance * m.expected_m);
}

std::string format_mm(double metres) {
  const double mm = metres * 1000.0;
  if (std::abs(mm) >= 10) return fmt::format("{:.0f} mm", mm);
  return fmt::format("{:.1f} mm", mm);
}

std::vector<Finding> evaluate_layer(const LayerFigures& f, const QualityThresholds& t) {
  std::vector<Finding> out = evaluate_unsorted(f, t);
  std::stable_sort(out.begin(), out.end(),
                   [](const Finding& a, const Finding& b) { return int(a.severity) < int(b.severity); });
  return out;
}

namespace {

// The findings of one layer, in the order the rules ran.
struct Findings {
  std::vector<Finding> out;
  void add(Severity s, std::string rule, std::string message, std::string advice) {
    out.push_back({s, std::move(rule), std::move(message), std::move(advice)});
  }
};

// False when nothing further can be judged (no photos, or not aligned yet).
bool photo_rules(const LayerFigures& f, const QualityThresholds& t, Findings& r) {
  if (f.photos == 0) {
    r.add(Severity::problem, "no_photos", "no photos have been imported for this layer",
        fmt::format("photograph the layer (30-60 photos, markers in view) and run: strata import photos DIR "
                    "--layer {} PHOTOS...", f.layer));
    return false;
  }
  if (f.photos < t.min_photos) {
    r.add(Severity::warning, "few_photos",
        fmt::format("only {} {} of this layer (at least {} recommended)", f.photos, photos_word(f.photos), t.min_photos),
        "walk once more around the trench taking overlapping photos (every step, about 60-80 % overlap)");
  }
  if (!f.aligned) {
    r.add(Severity::problem, "not_processed", "the photos have not been aligned yet: no quality figures exist",
        fmt::format("run: strata process DIR --layer {}", f.layer));
    return false;
  }
  return true;
}

void alignment_rules(const LayerFigures& f, const QualityThresholds& t, Findings& r) {
  if (!f.unaligned.empty()) {
    const int n = int(f.unaligned.size());
    const double fraction = double(n) / double(std::max(1, f.photos));
    r.add(fraction > t.max_unaligned_fraction ? Severity::problem : Severity::note, "unaligned_photos",
        fmt::format("{} {} could not be aligned: {}", n, photos_word(n), list_names(f.unaligned)),
        fraction > t.max_unaligned_fraction
            ? "these photos overlap too little with the others or are blurred: retake that part of the walk with "
              "smaller steps between photos"
            : "nothing to do if the coverage map shows no gap; otherwise retake them with more overlap");
  }
  if (f.reprojection_rmse_px && *f.reprojection_rmse_px > t.max_reprojection_rmse_px) {
    r.add(Severity::warning, "reprojection_rmse",
        fmt::format("mean reprojection error {:.2f} px exceeds {:.1f} px", *f.reprojection_rmse_px,
                    t.max_reprojection_rmse_px),
        "photos are probably blurred (camera shake, focus) or something moved (people, shadows, water): "
        "retake blurred photos with a faster shutter");
  }
}

std::string survey_words(const LayerFigures& f) {
  return f.survey_words.empty() ? "these photos and this survey" : f.survey_words;
}

// metres, 3D: the RMSE of the located markers of `role` that their survey and photos
// explain (the root mean square of their expected errors); 0 when nothing is known.
double expected_rmse_m(const LayerFigures& f, const std::string& role) {
  double sum = 0;
  int n = 0;
  for (const auto& m : f.markers) {
    if (m.role != role || !m.triangulated) continue;
    sum += m.expected_m * m.expected_m;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

// The survey's yardstick (docs/quality.md): over the fixed tolerance, a figure within
// `survey_allowance` times what the survey explains is as good as that survey allows
// (a warning: new photos would not help); beyond it, the markers disagree (a problem).
void rmse_rule(const LayerFigures& f, const QualityThresholds& t, const std::string& role, double rmse,
               double tolerance, const char* advice, Findings& r) {
  if (rmse <= tolerance) return;
  const double expected = expected_rmse_m(f, role);
  const double allowed = t.survey_allowance * expected;
  if (rmse <= allowed) {
    r.add(Severity::warning, role + "_rmse_survey",
        fmt::format("{} RMSE {} on {} (about {} expected): as close as that survey allows, but over the {} "
                    "tolerance",
                    role, format_mm(rmse), survey_words(f), format_mm(expected), format_mm(tolerance)),
        "no new photos needed; for plans at that tolerance, survey the markers to the millimetre (total "
        "station), import them with their sigma, and process the layer again");
    return;
  }
  const std::string beyond =
      !f.survey_words.empty() ? fmt::format(", and more than {} explains (about {} expected)", survey_words(f), format_mm(expected))
                   : std::string();
  r.add(Severity::problem, role + "_rmse",
      fmt::format("{} RMSE {} exceeds {}{}", role, format_mm(rmse), format_mm(tolerance), beyond), advice);
}

void marker_rules(const LayerFigures& f, const QualityThresholds& t, Findings& r) {
  for (const auto& m : f.markers) {
    if (m.role == "rejected") {
      r.add(Severity::warning, "marker_rejected",
          fmt::format("marker {} was rejected as an outlier ({} off)", m.name, format_mm(m.residual_m.norm())),
          fmt::format("check the surveyed coordinates of {} and that its target is the right one", m.name));
      continue;
    }
    if (!m.triangulated) {
      r.add(Severity::warning, "marker_not_located",
          fmt::format("marker {} could not be located (seen in {} {})", m.name, m.images, photos_word(m.images)),
          fmt::format("take photos that show {} clearly from at least {} positions", m.name, t.min_marker_photos));
      continue;
    }
    if (m.images < t.min_marker_photos) {
      r.add(Severity::warning, "marker_photos",
          fmt::format("marker {} seen in only {} {}", m.name, m.images, photos_word(m.images)),
          fmt::format("take {} more photos that show {} from different positions", t.min_marker_photos - m.images + 1,
                      m.name));
    }
    // A residual the survey explains is no sign of a wrong marker: the RMSE rules
    // judge the layer as a whole against that survey.
    const double allowed = allowed_marker_residual_m(m, t);
    if (m.residual_m.norm() > allowed) {
      const std::string over = allowed > t.max_marker_residual_m
                                   ? fmt::format("over {}: {:g} times what {} explains", format_mm(allowed),
                                                 t.survey_allowance, survey_words(f))
                                   : fmt::format("over {}", format_mm(allowed));
      r.add(Severity::warning, "marker_residual",
          fmt::format("{} marker {} is {} from its surveyed position ({})", m.role, m.name,
                      format_mm(m.residual_m.norm()), over),
          fmt::format("check the survey of {} (typing error, wrong target, moved marker)", m.name));
    }
  }
}

void georeference_rules(const LayerFigures& f, const QualityThresholds& t, Findings& r) {
  int control = 0, check = 0;
  for (const auto& m : f.markers) {
    if (m.role == "control" && m.triangulated) ++control;
    if (m.role == "check" && m.triangulated) ++check;
  }
  if (!f.georeferenced) {
    r.add(Severity::problem, "not_georeferenced",
        "layer not georeferenced: it has no real-world position, scale or orientation" +
            (f.georeference_message.empty() ? std::string() : " (" + f.georeference_message + ")"),
        fmt::format("place at least {} surveyed markers around the trench, visible in the photos; survey them and "
                    "run: strata import markers DIR survey.csv, then process the layer again",
                    t.min_control_markers));
  } else if (control < t.min_control_markers) {
    r.add(Severity::problem, "few_control_markers",
        fmt::format("only {} control {} located (at least {} needed)", control, control == 1 ? "marker" : "markers",
                    t.min_control_markers),
        "make sure at least 3 control markers, spread around the trench, each appear in 3 or more photos");
  }
  marker_rules(f, t, r);
  if (f.georeferenced && f.control_rmse_m) {
    rmse_rule(f, t, "control", *f.control_rmse_m, t.max_control_rmse_m,
              "check the survey of the markers with the largest residuals in the table below, then process again",
              r);
  }
  if (f.georeferenced && f.check_rmse_m) {
    rmse_rule(f, t, "check", *f.check_rmse_m, t.max_check_rmse_m,
              "the model is less accurate than required: add control markers on the side of the worst check "
              "marker, or check its survey",
              r);
  }
  if (f.georeferenced && check == 0) {
    r.add(Severity::note, "no_check_markers", "no check marker: the accuracy is not measured independently",
        "survey one more marker and mark it as 'check' in the survey file");
  }
}

void coverage_rules(const LayerFigures& f, const QualityThresholds& t, Findings& r) {
  if (f.coverage_known) {
    for (const auto& g : f.gaps) {
      const int more = std::max(2, t.min_photos_per_area - g.min_count + 1);
      const std::string side = side_to_photograph(g, f.camera_centres, f.trench_centre);
      r.add(Severity::problem, "coverage_gap",
          f.georeferenced ? fmt::format("the {} is seen by fewer than {} photos ({:.0f} % of it, {:.2f} m²)",
                                        g.sector.name, t.min_photos_per_area, 100 * g.fraction, g.area_m2)
                          : fmt::format("the {} is seen by fewer than {} photos ({:.0f} % of it)", g.sector.name,
                                        t.min_photos_per_area, 100 * g.fraction),
          side.empty() ? fmt::format("take {} more photos from above the centre of the trench, looking down", more)
                       : fmt::format("take {} more photos from the {} side, aimed at the {}", more, side,
                                     g.sector.name));
    }
    // Without markers the layer has no scale: its ground resolution is in arbitrary
    // units, and the not_georeferenced problem already says what to do.
    if (!f.georeferenced) return;
    // When most of the trench falls short, one finding says so: nine sector
    // messages would bury the other findings.
    constexpr std::size_t kMostSectors = 5;
    if (f.low_resolution.size() >= kMostSectors) {
      double worst = 0;
      for (const auto& g : f.low_resolution) worst = std::max(worst, g.worst_gsd_m);
      r.add(Severity::warning, "low_resolution",
          fmt::format("most of the trench ({} of 9 parts) is photographed only at low resolution (down to {} per "
                      "pixel, over {})",
                      f.low_resolution.size(), format_mm(worst), format_mm(t.max_gsd_m)),
          "photograph from closer (about 1-1.5 m from the surface) or at the camera's full resolution");
    }
    for (const auto& g : f.low_resolution.size() >= kMostSectors ? std::vector<CoverageShortfall>{} : f.low_resolution) {
      const std::string side = side_to_photograph(g, f.camera_centres, f.trench_centre);
      r.add(Severity::warning, "low_resolution",
          fmt::format("the {} is photographed only at low resolution ({} per pixel at best, over {})", g.sector.name,
                      format_mm(g.worst_gsd_m), format_mm(t.max_gsd_m)),
          side.empty() ? "take a few photos closer to the centre of the trench"
                       : fmt::format("take a few photos closer to the {} from the {} side", g.sector.name, side));
    }
  } else {
    r.add(Severity::note, "coverage_unknown", "the photo coverage could not be mapped (no plan of the surface)",
        "process the layer to the products stage for a full coverage map");
  }
}

void later_stage_rules(const LayerFigures& f, Findings& r) {
  if (!f.dense) {
    r.add(Severity::note, "no_dense", "no dense surface yet",
        fmt::format("run: strata process DIR --layer {} (the dense stage follows the alignment)", f.layer));
  } else if (!f.products) {
    r.add(Severity::note, "no_products", "no DTM or orthophoto yet",
        fmt::format("run: strata process DIR --layer {} --until products", f.layer));
  }
}

std::vector<Finding> evaluate_unsorted(const LayerFigures& f, const QualityThresholds& t) {
  Findings r;
  if (!photo_rules(f, t, r)) return r.out;
  alignment_rules(f, t, r);
  georeference_rules(f, t, r);
  coverage_rules(f, t, r);
  later_stage_rules(f, r);
  return r.out;
}

}  // namespace
}  // namespace strata
