// common/: what every stage shares (see each header).
#pragma once

#include "common/data_dir.hpp"
#include "common/interrupt.hpp"
#include "common/json_input.hpp"
#include "common/located_issues.hpp"
#include "common/memory_budget.hpp"
#include "common/output_file.hpp"
#include "common/sha256.hpp"
#include "common/xxh128.hpp"
#include "common/stopwatch.hpp"
