// common/: what every stage shares (see each header).
#pragma once

#include "common/interrupt.hpp"
#include "common/json_input.hpp"
#include "common/memory_budget.hpp"
#include "common/output_file.hpp"
