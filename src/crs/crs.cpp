#include "crs/crs.hpp"

#include "core/error.hpp"

#include <proj.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <regex>

namespace strata {
namespace {

// One PROJ context per thread of use; PJ objects are cleaned up by RAII.
struct ContextDeleter {
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};
struct PjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using ContextPtr = std::unique_ptr<PJ_CONTEXT, ContextDeleter>;
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

ContextPtr make_context() {
  ContextPtr ctx(proj_context_create());
  proj_log_level(ctx.get(), PJ_LOG_NONE);
  return ctx;
}

std::string trim(std::string s) {
  auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

// Normalises what people type into something proj_create understands.
std::string normalise(const std::string& text) {
  std::string t = trim(text);
  static const std::regex bare_number(R"(^\d{4,6}$)");
  if (std::regex_match(t, bare_number)) return "EPSG:" + t;
  // OpenDroneMap: "WGS84 UTM 32N" (zone and hemisphere letter).
  static const std::regex odm_utm(R"(^WGS\s*84\s+UTM\s+(\d{1,2})\s*([NSns])$)",
                                  std::regex::icase);
  std::smatch m;
  if (std::regex_match(t, m, odm_utm)) {
    const int zone = std::stoi(m[1]);
    const bool north = std::toupper(static_cast<unsigned char>(m[2].str()[0])) == 'N';
    return "EPSG:" + std::to_string((north ? 32600 : 32700) + zone);
  }
  if (t.rfind("+proj", 0) == 0 && t.find("+type=crs") == std::string::npos) {
    t += " +type=crs";
  }
  return t;
}

PjPtr create_crs(PJ_CONTEXT* ctx, const std::string& text) {
  const std::string norm = normalise(text);
  PjPtr crs(proj_create(ctx, norm.c_str()));
  if (!crs) throw CrsError(fmt::format("unknown CRS '{}'", text));
  const PJ_TYPE type = proj_get_type(crs.get());
  if (type == PJ_TYPE_BOUND_CRS) {
    PjPtr base(proj_get_source_crs(ctx, crs.get()));
    if (base) return base;
  }
  return crs;
}

}  // namespace

std::string CrsInfo::label() const {
  return code ? fmt::format("{}:{}", authority, code) : name;
}

CrsInfo describe_crs(const std::string& text) {
  auto ctx = make_context();
  PjPtr crs = create_crs(ctx.get(), text);
  CrsInfo info;
  info.input = text;
  if (const char* n = proj_get_name(crs.get())) info.name = n;
  if (const char* auth = proj_get_id_auth_name(crs.get(), 0)) {
    info.authority = auth;
    if (const char* code = proj_get_id_code(crs.get(), 0)) info.code = std::atoi(code);
  } else {
    // A PROJ string or WKT without an id: ask PROJ for the equivalent EPSG entry.
    int* confidence = nullptr;
    PJ_OBJ_LIST* matches = proj_identify(ctx.get(), crs.get(), "EPSG", nullptr, &confidence);
    // PROJ strings carry no axis order and name no datum ensemble, so PROJ gives
    // its best match 70 % confidence; accept it when the two are equivalent.
    PjPtr best;
    if (matches && proj_list_get_count(matches) > 0 && confidence) {
      best.reset(proj_list_get(ctx.get(), matches, 0));
      const bool equivalent =
          proj_is_equivalent_to_with_ctx(ctx.get(), best.get(), crs.get(),
                                          PJ_COMP_EQUIVALENT_EXCEPT_AXIS_ORDER_GEOGCRS) != 0;
      if (!(confidence[0] >= 90 || (confidence[0] >= 70 && equivalent))) best.reset();
    }
    if (best) {
      info.authority = "EPSG";
      info.code = std::atoi(proj_get_id_code(best.get(), 0));
      info.name = proj_get_name(best.get());
      crs = std::move(best);
    }
    proj_int_list_destroy(confidence);
    proj_list_destroy(matches);
  }
  const PJ_TYPE type = proj_get_type(crs.get());
  info.projected = type == PJ_TYPE_PROJECTED_CRS;
  info.geographic = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  const char* wkt_options[] = {"MULTILINE=NO", nullptr};
  if (const char* wkt = proj_as_wkt(ctx.get(), crs.get(), PJ_WKT1_GDAL, wkt_options)) info.wkt = wkt;
  if (info.wkt.empty()) {
    if (const char* wkt = proj_as_wkt(ctx.get(), crs.get(), PJ_WKT2_2019, wkt_options)) info.wkt = wkt;
  }
  if (const char* json = proj_as_projjson(ctx.get(), crs.get(), nullptr)) info.projjson = json;
  PjPtr cs(proj_crs_get_coordinate_system(ctx.get(), crs.get()));
  if (cs && proj_cs_get_axis_count(ctx.get(), cs.get()) > 0) {
    double to_metre = 0;
    const char* unit_name = nullptr;
    proj_cs_get_axis_info(ctx.get(), cs.get(), 0, nullptr, nullptr, nullptr, &to_metre,
                          &unit_name, nullptr, nullptr);
    info.metres = info.projected && std::abs(to_metre - 1.0) < 1e-12;
  }
  return info;
}

std::optional<AreaOfUse> area_of_use(const std::string& text) {
  auto ctx = make_context();
  PjPtr crs = create_crs(ctx.get(), text);
  AreaOfUse a;
  const char* name = nullptr;
  if (!proj_get_area_of_use(ctx.get(), crs.get(), &a.west, &a.south, &a.east, &a.north, &name)) return std::nullopt;
  if (a.west <= -1000 || a.south <= -1000) return std::nullopt;  // PROJ's "unknown"
  if (name) a.name = name;
  return a;
}

void require_site_crs(const CrsInfo& crs) {
  if (crs.geographic) {
    throw CrsError(fmt::format(
        "site CRS '{}' ({}) is geographic (degrees); a site needs a projected CRS in metres, "
        "e.g. the UTM zone of the site such as EPSG:32636",
        crs.input, crs.name));
  }
  if (!crs.projected) {
    throw CrsError(fmt::format("site CRS '{}' ({}) is not a projected CRS", crs.input, crs.name));
  }
  if (!crs.metres) {
    throw CrsError(fmt::format("site CRS '{}' ({}) does not use metres", crs.input, crs.name));
  }
}

struct CrsTransform::Impl {
  ContextPtr ctx;
  PjPtr op;
};

CrsTransform::CrsTransform(const std::string& from, const std::string& to)
    : impl_(std::make_unique<Impl>()) {
  impl_->ctx = make_context();
  PjPtr a = create_crs(impl_->ctx.get(), from);
  PjPtr b = create_crs(impl_->ctx.get(), to);
  identity_ = proj_is_equivalent_to(a.get(), b.get(), PJ_COMP_EQUIVALENT) != 0;
  PjPtr op(proj_create_crs_to_crs_from_pj(impl_->ctx.get(), a.get(), b.get(), nullptr, nullptr));
  if (!op) throw CrsError(fmt::format("no transformation from '{}' to '{}'", from, to));
  impl_->op.reset(proj_normalize_for_visualization(impl_->ctx.get(), op.get()));
  if (!impl_->op) throw CrsError(fmt::format("no transformation from '{}' to '{}'", from, to));
}

CrsTransform::~CrsTransform() = default;
CrsTransform::CrsTransform(CrsTransform&&) noexcept = default;
CrsTransform& CrsTransform::operator=(CrsTransform&&) noexcept = default;

Eigen::Vector3d CrsTransform::apply(const Eigen::Vector3d& p) const {
  if (identity_) return p;
  PJ_COORD c = proj_coord(p.x(), p.y(), p.z(), HUGE_VAL);
  PJ_COORD r = proj_trans(impl_->op.get(), PJ_FWD, c);
  if (!std::isfinite(r.xyz.x) || !std::isfinite(r.xyz.y)) {
    throw CrsError(fmt::format("coordinate ({}, {}, {}) cannot be transformed into the site CRS",
                               p.x(), p.y(), p.z()));
  }
  return {r.xyz.x, r.xyz.y, std::isfinite(r.xyz.z) ? r.xyz.z : p.z()};
}

CrsTransform transform_into_site(const std::string& from, const std::string& site_crs, const std::string& context) {
  try {
    describe_crs(from);
    return CrsTransform(from, site_crs);
  } catch (const CrsError& e) {
    throw CrsError(fmt::format("{}: {}", context, e.what()));
  }
}

}  // namespace strata
