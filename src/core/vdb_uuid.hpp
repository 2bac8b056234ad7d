#pragma once
// OpenVDB writes a random UUID into every file's header (io::Archive::writeHeader),
// so two writes of the same grids differ in 36 bytes and their checksums differ.
// strata promises that products are reproducible bit for bit:
// after writing a .vdb it replaces that UUID by one derived from the file's content.
#include <filesystem>

namespace strata {

// Rewrites, in place, the UUID of the OpenVDB file at `path` as the first 128 bits of
// the SHA-256 of the file with those 36 bytes zeroed (the UUID's form kept, version
// nibble 4). Throws IoError naming the file when it is not an OpenVDB file whose
// header carries a UUID where the format puts it.
void make_vdb_uuid_from_content(const std::filesystem::path& path);

}  // namespace strata
