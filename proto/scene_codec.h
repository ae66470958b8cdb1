// The JSON scene format (proto/SCENE.md, proto/scene.schema.json): reading, and writing only
// what differs from the defaults. Reading checks the format (types, unknown fields, shapes);
// the scene's rules (ValidateScene) are checked once, where the scene is prepared
// (Problem::Build), so that a scene read, stored and run is not validated again at each step.
#pragma once

#include <string>
#include <string_view>

#include "engine/api/scene.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// Reads a scene (types, unknown fields, shapes). Throws InputError naming the JSON path of the
// first problem. The result is valid only once Problem::Build (or ValidateScene) accepts it.
Scene SceneFromJson(const Json& json);
Scene SceneFromText(std::string_view text);
// Reads a file; a file that cannot be read is an InputError with an empty path.
Scene LoadSceneFile(const std::string& path);

// The scene as JSON: fields equal to their defaults are left out.
Json SceneToJson(const Scene& scene);

// The units the numbers are in (DeriveUnits: the scene's length and force, and the stiffness,
// modulus, mass and time they imply), as results and exported models state them.
Json UnitsToJson(const DerivedUnits& units);
// The same units in words, as the run's summary and the dashboard say them: "length mm, force
// mN, stiffness mN/mm, mass kg, time s (E is relative: no unit)". Empty for a result without
// units (null, or written before a result had them).
std::string UnitsText(const Json& units);
// A scene's `search` member alone, both ways (the same rules and paths as in a scene): what
// `submit` reads, applies its flags to and writes back.
SearchSettings SearchSettingsFromJson(const Json& json);
Json SearchSettingsToJson(const SearchSettings& settings);

// An array of node pairs [[i, j], ...] as written (not reordered or range-checked), and back.
std::vector<NodePair> ReadNodePairs(const Json& json, const std::string& path);
Json PairsToJson(const std::vector<NodePair>& pairs);

// Flat d*n coordinates as an array of n points [[x, y], ...].
Json PointsToJson(const Vector& flat, int dimension);

// One load case as the scene format writes it (node sets by name where they were given so).
Json LoadCaseToJson(const LoadCase& load_case, int dimension);

// The candidates of a scene with an FEM reference that names none: the mesh's edges and the
// 8 nearest neighbours of every node (proto/SCENE.md).
CandidateSpec FemDefaultCandidates();

// Reads a whole file into a string; throws InputError when it cannot.
std::string ReadFile(const std::string& path);

}  // namespace springfit::proto
