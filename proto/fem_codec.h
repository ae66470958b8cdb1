// The JSON form of a finite-element reference (proto/SCENE.md, "fem"): read into and written
// from Reference::fem. Used by scene_codec.cpp.
#pragma once

#include "engine/api/scene.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// Reads the fields of a reference of type fem (the caller has checked the keys and the type).
// Throws InputError naming the JSON path.
void ReadFemReference(const Json& v, int dimension, FemReference& fem);
// Writes the fields of a reference of type fem into `r` (which already holds "type").
void WriteFemReference(const FemReference& fem, Json& r);

}  // namespace springfit::proto
