// A higher layer (tests/layers).
#pragma once
#include "low/a.hpp"
