#define CATCH_CONFIG_MAIN
// Catch 2.13 indents a header's lines after its first ": " by that column, and its text wrapping never
// ends once the indent reaches the console width: a failing test named with a late ": " hung instead
// of failing (scripts/check_test_names.py, a ctest, keeps names clear of it). A wider console keeps
// the margin.
#define CATCH_CONFIG_CONSOLE_WIDTH 160
#include <catch2/catch.hpp>
