#pragma once
// Files written through a temporary name in the same folder and renamed over their
// final name when complete (rename is atomic on POSIX): whenever the process dies,
// the file is whole, the old one or the new one. The one way strata writes a file
// that is not staged with others (core/staged_files.hpp groups several).
#include <filesystem>
#include <functional>
#include <string_view>

namespace strata {

// `write(tmp)` creates and fills `tmp` (a stream, GDAL, OpenVDB: any writer), then
// `tmp` takes the name `path`. The folder is created when missing. When `write`
// throws, or the rename fails, the temporary is removed and `path` left as it was;
// a failure of the file system is an IoError "<what>: <path>: <why>". `fault_point`
// (core/fault.hpp) is passed once the temporary is complete, before the rename.
void write_atomically(const std::filesystem::path& path, std::string_view what,
                      const std::function<void(const std::filesystem::path& tmp)>& write,
                      std::string_view fault_point = {});

// The same, with the file's bytes.
void write_bytes_atomically(const std::filesystem::path& path, std::string_view what, std::string_view bytes,
                            std::string_view fault_point = {});

// The same, a copy of `source`.
void copy_atomically(const std::filesystem::path& source, const std::filesystem::path& path, std::string_view what,
                     std::string_view fault_point = {});

}  // namespace strata
