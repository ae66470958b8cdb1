// A genome packed 8 genes per byte (gene i in bit i % 8 of byte i / 8): the GA cache's key,
// and the form in which checkpoints and both stores keep genomes on disk. One format, here:
// changing it changes every stored job's bytes.
#pragma once

#include <string>

#include "engine/genome/genome.h"

namespace springfit {

std::string PackGenome(const Genome& genome);
// The genome of `packed`, `genes` long (bits beyond the packed bytes are 0).
Genome UnpackGenome(const std::string& packed, int genes);

}  // namespace springfit
