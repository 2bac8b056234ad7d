#pragma once
// The shading of a DTM as GIS hillshades draw it (Burrough & McDonnell 1998,
// Principles of GIS, ch. 8; gdaldem's and ESRI's): max(0, n . s), with n the surface
// normal from Horn's (1981) 3x3 slopes and s the direction to a sun at azimuth 315
// degrees (north-west, clockwise from north) and altitude 45 degrees. One function for
// the field report's hillshade and the field station's map tiles. Std only.
#include <cstdint>
#include <vector>

namespace strata {

struct HeightGrid {
  int width = 0, height = 0;            // cells; rows run from north to south
  double cell_e = 0, cell_n = 0;        // metres (or the frame's units) per cell, east and north
  const float* z = nullptr;             // width x height heights, row by row
  const std::uint8_t* valid = nullptr;  // nonzero where z holds a height
};

// Per cell, the shade in [0, 1]; NaN where the cell has no height. A neighbour outside
// the grid or without a height takes the cell's own (the edge of a DTM is shaded as
// if level there rather than left out).
std::vector<float> hillshade(const HeightGrid& grid);

}  // namespace strata
