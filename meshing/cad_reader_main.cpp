// rodfab-cad-reader: the CAD reader process (cad_reader.hpp). Reads one STEP or IGES file with
// OpenCASCADE into rods and answers on file descriptor 3 (detail::resultJson or detail::errorJson).
// Run by rodsFromCad, not by people: its arguments are detail::readerArguments'.
#include "common/memory_budget.hpp"
#include "meshing/cad_reader.hpp"

#include <Standard_Failure.hxx>

#include <sys/prctl.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <new>
#include <string>
#include <vector>

namespace {

using namespace rodfab::meshing;

bool writeAll(int fd, const std::string& text) {
  for (std::size_t done = 0; done < text.size();) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

// MeshError's message without the "FILE: " its what() starts with (rodsFromCad adds it again).
std::string withoutFile(const MeshError& e) {
  const std::string what = e.what(), prefix = e.file().string() + ": ";
  return what.starts_with(prefix) ? what.substr(prefix.size()) : what;
}

std::string answer(const detail::CadReaderRequest& request) {
  try {
    return detail::resultJson(detail::readCadDesign(request.file, request.options));
  } catch (const MeshError& e) {
    return detail::errorJson(withoutFile(e));
  } catch (const rodfab::common::OutOfMemory& e) {
    return detail::errorJson(e.what());
  } catch (const std::bad_alloc&) {
    return detail::errorJson("reading the model ran out of memory (the memory budget, --max-memory, is " +
                             std::to_string(request.memoryBudget >> 20) +
                             " MiB): raise --max-memory, or split the model");
  } catch (const Standard_Failure& e) {
    return detail::errorJson(std::string("OpenCASCADE failed: ") + e.GetMessageString());
  } catch (const std::exception& e) {
    return detail::errorJson(e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Ends with rodfab, whatever ends rodfab (the watchdog's _exit, a SIGKILL).
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  detail::CadReaderRequest request;
  try {
    request = detail::fromReaderArguments(std::vector<std::string>(argv + 1, argv + argc));
    // rodfab ended before the request above took effect (compared by pid, not with 1: rodfab may be a
    // container's first process).
    if (request.parentProcess != static_cast<long>(::getppid())) return 2;
    // The caller's budget, and with it the data limit: OpenCASCADE's allocations beyond it fail here.
    rodfab::common::setMemoryBudget(request.memoryBudget);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rodfab-cad-reader: %s (it is run by rodfab rods-from-cad)\n", e.what());
    return 2;
  }
  return writeAll(detail::kResultDescriptor, answer(request)) ? 0 : 1;
}
