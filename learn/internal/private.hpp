#pragma once
// Included first by every header in learn/internal/: they are private to scout_learn and its
// tests by construction, since only targets linking the CMake target scout_learn_internal get
// SCOUT_LEARN_INTERNAL.
#ifndef SCOUT_LEARN_INTERNAL
#error \
    "learn/internal/ is private to scout_learn and its tests (CMake target scout_learn_internal); include learn/*.hpp"
#endif
