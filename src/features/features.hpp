#pragma once
// The features stage, all of it: extraction, pair selection, matching and
// verification, coded targets. See docs/features.md.
#include "features/extraction.hpp"
#include "features/matching.hpp"
#include "features/targets.hpp"
#include "features/types.hpp"
