// The engine's public surface (engine/api/): analyses shown beside a scene or a model: which
// springs the load cases identify, the FEM mesh's measures and quality, the probe fit's and the
// certificate's reports (probe families, E summaries, pencils).
#pragma once

#include "engine/direct/identifiability_report.h"
#include "engine/fem/mesh_facts.h"
#include "engine/probe_fit/probe_fit_report.h"
