// rodsFromCad through the CAD module: OpenCASCADE's 18 libraries are loaded with the module on the
// first CAD file, not with rodfab. Linked into rodfab, their symbol relocations cost every command
// about 37 ms of its 83 ms start (perf of `rodfab --version`, 2026-12-03), for the one command that
// reads CAD files.
#include "meshing/cad_module.hpp"

#include <dlfcn.h>

#include <mutex>
#include <string>

namespace rodfab::meshing {

namespace {

// Where this library was loaded from: the module lies beside it, in the build tree and when installed.
const char kAnchor = 0;

struct LoadedModule {
  detail::CadReader reader = nullptr;
  std::string path, error;
};

LoadedModule load() {
  LoadedModule m;
  Dl_info self{};
  if (::dladdr(&kAnchor, &self) == 0 || self.dli_fname == nullptr) {
    m.error = "cannot tell where librodfab_meshing was loaded from";
    return m;
  }
  m.path = (std::filesystem::path(self.dli_fname).parent_path() / RODFAB_CAD_MODULE).string();
  // Kept loaded for the process's life: OpenCASCADE's static objects are not made to be unloaded.
  void* handle = ::dlopen(m.path.c_str(), RTLD_NOW | RTLD_LOCAL);
  void* entry = handle ? ::dlsym(handle, kCadReaderSymbol) : nullptr;
  if (!entry) {
    const char* why = ::dlerror();
    m.error = why ? why : "no entry point";
    return m;
  }
  m.reader = reinterpret_cast<detail::CadReader (*)()>(entry)();
  return m;
}

}  // namespace

CadRods rodsFromCad(const std::filesystem::path& cadFile, const CadRodOptions& options) {
  static std::once_flag once;
  static LoadedModule module;
  std::call_once(once, [] { module = load(); });
  if (!module.reader)
    throw MeshError(cadFile, "cannot read CAD files: the CAD module " + (module.path.empty() ? std::string(RODFAB_CAD_MODULE) : module.path) +
                                 " did not load (" + module.error + "); rodfab's installation is incomplete");
  return module.reader(cadFile, options);
}

}  // namespace rodfab::meshing
