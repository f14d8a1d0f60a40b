#pragma once
// Logging goes through spdlog's default logger; this header only fixes the include so passes
// and tools log the same way.
#include <spdlog/spdlog.h>
