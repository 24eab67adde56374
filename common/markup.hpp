// Text placed in XML (the GrabCAD .gcvf) or HTML (the job report).
#pragma once

#include <string>
#include <string_view>

namespace rodfab::common {

// `text` with & < > " ' replaced by character references, safe inside XML and HTML elements and
// quoted attributes alike (the apostrophe as &#39;, which both languages read). Thread-safe.
std::string escapeMarkup(std::string_view text);

}  // namespace rodfab::common
