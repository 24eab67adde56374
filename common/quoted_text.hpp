// Text from an input file placed in a message: a hostile file's bytes must not reach the terminal
// as control sequences (an ESC in a PLY element name would be a command to the technician's
// terminal), nor flood it. And numbers a message names as limits, exactly.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace rodfab::common {

// `text` as a message may show it: control characters (C0, DEL and the C1 range U+0080-U+009F),
// bytes that are not valid UTF-8, the apostrophe and the backslash written as \xNN (\x1b, \x27,
// \x5c), other UTF-8 characters kept; cut after `maxBytes` bytes of `text`, the cut marked "...".
// Thread-safe.
std::string printableFromFile(std::string_view text, std::size_t maxBytes = 40);
// Whether `text` holds a control character (C0, DEL, or C1 as UTF-8: U+0080-U+009F) or is not valid
// UTF-8: what a name from a file (a rod's, a load case's) may not hold.
bool holdsControlCharacters(std::string_view text);
// The same between apostrophes, as a message shows a file's word: 'floz', 'x\x1b[2J'.
std::string quotedFromFile(std::string_view text, std::size_t maxBytes = 40);

// The shortest text that reads back as `v` (std::to_chars): a limit a message names is the limit, not
// a rounding that a value just past it would print as ("outside [8, 2017.46]" for 2017.4567). 1e+300,
// inf, nan as to_chars writes them. Thread-safe.
std::string exactNumber(double v);

}  // namespace rodfab::common
