#pragma once
// A Wavefront OBJ file as a viewer reads it, parsed by the tests themselves (no OBJ
// library): the statements strata's writers use.
#include "support/test_support.hpp"

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace strata::test {

// What a viewer reads from an OBJ file: the statements the writer uses, each face's
// v/vt/vn indices (1-based, 0 when absent) and the material it is in.
struct ObjFile {
  std::map<std::string, std::string> comments;  // "# key rest": key -> rest ("crs" -> "EPSG:32636")
  Eigen::Vector3d origin = Eigen::Vector3d::Constant(std::nan(""));  // from "# origin E N Z (...)"
  std::string mtllib;
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3d> rgb;  // per v when coloured
  std::vector<Eigen::Vector2d> vt;
  std::vector<Eigen::Vector3d> vn;
  std::vector<std::array<std::array<int, 3>, 3>> f;  // [corner][v, vt, vn]
  std::vector<std::string> face_material;
};

inline ObjFile read_obj(const std::filesystem::path& path) {
  ObjFile o;
  std::istringstream in(test::read_text(path));
  std::string line, material;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "#") {
      std::string key, rest;
      ls >> key >> std::ws;
      std::getline(ls, rest);
      o.comments[key] = rest;
      if (key == "origin") std::istringstream(rest) >> o.origin.x() >> o.origin.y() >> o.origin.z();
    } else if (tag == "mtllib") {
      ls >> o.mtllib;
    } else if (tag == "usemtl") {
      ls >> material;
    } else if (tag == "v") {
      Eigen::Vector3d p, c;
      ls >> p.x() >> p.y() >> p.z();
      o.v.push_back(p);
      if (ls >> c.x() >> c.y() >> c.z()) o.rgb.push_back(c);
    } else if (tag == "vt") {
      Eigen::Vector2d t;
      ls >> t.x() >> t.y();
      o.vt.push_back(t);
    } else if (tag == "vn") {
      Eigen::Vector3d n;
      ls >> n.x() >> n.y() >> n.z();
      o.vn.push_back(n);
    } else if (tag == "f") {
      std::array<std::array<int, 3>, 3> face{};
      for (auto& corner : face) {
        std::string c;
        ls >> c;
        std::istringstream cs(c);
        std::string part;
        for (int k = 0; k < 3 && std::getline(cs, part, '/'); ++k) corner[k] = part.empty() ? 0 : std::stoi(part);
      }
      o.f.push_back(face);
      o.face_material.push_back(material);
    }
  }
  return o;
}

}  // namespace strata::test
