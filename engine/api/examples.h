// The engine's public surface (engine/api/): the built-in example scenes.
#pragma once

#include "engine/examples/catalog.h"
