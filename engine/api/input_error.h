// The engine's public surface (engine/api/): the error that names a file, field or index of
// bad input, and numbers written for people.
#pragma once

#include "engine/input_error.h"
#include "engine/number_text.h"
