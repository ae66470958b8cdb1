// The engine's public surface (engine/api/): analyses shown beside a scene or a model: which
// springs the load cases identify, the FEM mesh's model and quality, the probe fit's and the
// certificate's reports (probe families, E summaries, pencils).
#pragma once

#include "engine/direct/identifiability.h"
#include "engine/fem/fem_model.h"
#include "engine/probe_fit/probe_fit_report.h"
