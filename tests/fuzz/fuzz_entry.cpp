// The libFuzzer entry point of one target, chosen when compiling:
// -DSTRATA_FUZZ_TARGET=markers_csv makes the executable fuzz_markers_csv.
#include "fuzz/targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return strata::fuzz::STRATA_FUZZ_TARGET(data, size);
}
