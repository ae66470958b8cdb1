// The engine's public surface (engine/api/): the error that names a file, field or index of
// bad input, and numbers written for people.
#pragma once

#include "engine/runtime/input_error.h"
#include "engine/runtime/number_text.h"
