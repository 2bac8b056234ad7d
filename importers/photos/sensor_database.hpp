#pragma once
#include <optional>
#include <string>

namespace strata {

// Sensor width (mm, long side) of a camera from the shipped list, matching make
// by prefix and model exactly, both case-insensitively and with spaces collapsed.
std::optional<double> lookup_sensor_width_mm(const std::string& make, const std::string& model);

}  // namespace strata
