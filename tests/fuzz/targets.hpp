#pragma once
// The fuzz targets: one function per parser of a file a user hands strata. Each
// takes the bytes of one input (libFuzzer's LLVMFuzzerTestOneInput signature) and
// returns 0; it throws FuzzFailure (fuzz_support.hpp) when the parser misbehaves.
// fuzz_entry.cpp makes one of them a libFuzzer executable; replay_test.cpp runs
// each over its corpus, tests/fuzz/corpus/<name>/.
#include <cstddef>
#include <cstdint>

namespace strata::fuzz {

using TargetFunction = int (*)(const std::uint8_t* data, std::size_t size);

int markers_csv(const std::uint8_t* data, std::size_t size);   // importer.markers.csv (format auto)
int markers_odm(const std::uint8_t* data, std::size_t size);   // importer.markers.odm, gcp_list
int photo(const std::uint8_t* data, std::size_t size);         // importer.photos: check, EXIF, focal prior
int calibration(const std::uint8_t* data, std::size_t size);   // importer.calibration.{opencv,metashape}
int ply(const std::uint8_t* data, std::size_t size);           // reader.ply
int footprint(const std::uint8_t* data, std::size_t size);     // reader.footprint: trench outline GeoJSON
int target_names(const std::uint8_t* data, std::size_t size);  // --target-names id=name list
int project(const std::uint8_t* data, std::size_t size);       // opening someone else's project.gpkg
int geotiff(const std::uint8_t* data, std::size_t size);       // reader.dtm: a --surface raster
int section_options(const std::uint8_t* data, std::size_t size);  // strata export section's numbers
int volume_options(const std::uint8_t* data, std::size_t size);   // strata volume's numbers

struct Target {
  const char* name;  // also the corpus folder and the fuzz executable (fuzz_<name>)
  TargetFunction run;
};
inline constexpr Target kTargets[] = {
    {"markers_csv", markers_csv}, {"markers_odm", markers_odm}, {"photo", photo},
    {"calibration", calibration}, {"ply", ply},                 {"footprint", footprint},
    {"target_names", target_names}, {"project", project},
    {"geotiff", geotiff},         {"section_options", section_options}, {"volume_options", volume_options},
};

}  // namespace strata::fuzz
