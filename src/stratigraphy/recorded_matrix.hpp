#pragma once
// The Harris matrix as the project database records it.
#include "project/database.hpp"
#include "stratigraphy/harris_matrix.hpp"

namespace strata {

// Every unit and relation of the project (relation kinds the schema does not know
// are left out). Throws InputError if the recorded relations contain a cycle.
HarrisMatrix recorded_matrix(Database& db);

}  // namespace strata
