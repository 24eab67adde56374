#include "meshing/input_file.hpp"

#include "meshing/mesh.hpp"

#include <algorithm>
#include <cctype>
#include <system_error>

namespace rodfab::meshing::detail {

std::string lowerCaseExtension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

void requireExtension(const std::filesystem::path& file, std::string_view kind, std::initializer_list<std::string_view> extensions) {
  const std::string ext = lowerCaseExtension(file);
  if (std::find(extensions.begin(), extensions.end(), ext) != extensions.end()) return;
  std::string expected;
  std::size_t i = 0;
  for (const std::string_view e : extensions) {
    expected += (i == 0 ? "" : i + 1 == extensions.size() ? " or " : ", ");
    expected += e;
    ++i;
  }
  throw MeshError(file, "unknown " + std::string(kind) + " format '" + file.extension().string() + "': expected " + expected);
}

std::uintmax_t checkedFileSize(const std::filesystem::path& file, std::string_view tooLargeAdvice) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw MeshError(file, "no such file (or not a regular file)");
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) throw MeshError(file, "cannot read: " + ec.message());
  if (size > kMaxMeshFileBytes) throw MeshError(file, "larger than 2 GiB" + std::string(tooLargeAdvice));
  return size;
}

}  // namespace rodfab::meshing::detail
