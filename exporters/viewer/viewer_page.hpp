#pragma once
// writer.viewer: the site model in one self-contained HTML page (three.js from Debian's
// libjs-three inlined, the .glb models embedded as base64), for any browser offline:
// what `strata export viewer` writes and the field station's 3D page shows.
#include <string>

namespace strata {

// The embedded models (.glb bytes): `first` shown as soon as it is decoded, `detail`
// (may be empty) the full level of the layers `first` holds coarse.
struct ViewerModels {
  std::string first, detail;
};

// three.js (r111, the non-module builds that define the global THREE) and its glTF
// loader and orbit controls, as <script> elements. InputError naming the file when
// Debian's libjs-three is missing (STRATA_LIBJS_THREE_DIR replaces its folder).
std::string viewer_three_js();

// The page. `title` and `crs` are escaped; the script is the viewer's own (viewer_js.cpp).
std::string viewer_page(const std::string& title, const std::string& crs, const std::string& three_js,
                        const ViewerModels& models);

}  // namespace strata
