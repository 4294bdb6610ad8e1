// A lower layer that includes a higher one (tests/layers).
#pragma once
#include "high/b.hpp"
