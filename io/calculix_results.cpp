// CalculiX results as measured positions: nodal displacements from a .frd file (*NODE FILE, U)
// or a .dat file (*NODE PRINT, U), per step (mesh_import.h).
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "engine/api/input_error.h"
#include "io/mesh_import.h"
#include "io/text_output.h"

namespace springfit::io {
namespace {

using Displacements = std::map<long, std::array<double, 3>>;

[[noreturn]] void Fail(const std::string& path, int line, const std::string& message) {
  throw InputError("", path + ":" + std::to_string(line) + ": " + message);
}

double Field(const std::string& path, int line, const std::string& text) {
  const std::optional<double> value = NumberIn(text);
  if (!value) Fail(path, line, "expected a number, got '" + text + "'");
  return *value;
}

// .frd (ASCII): the DISP blocks; per step (the third integer of the "1PSTEP" record) the last
// one, its increment's end. Records are fixed-width: " -1", the node in 10 columns, then
// values in 12 columns each.
std::vector<Displacements> ReadFrd(const std::string& path, std::ifstream& in) {
  std::map<long, Displacements> by_step;
  std::string text;
  int number = 0;
  long step = 0;
  bool in_disp = false;
  int node_width = 10;  // the node's columns: 10 in the long format, 5 in the short one
  Displacements* block = nullptr;
  while (std::getline(in, text)) {
    ++number;
    if (text.rfind("    1PSTEP", 0) == 0) {
      const std::string rest = text.substr(10);
      std::istringstream fields(rest);
      long a = 0, b = 0, c = 0;
      if (!(fields >> a >> b >> c)) Fail(path, number, "a 1PSTEP record without its step");
      step = c;
      in_disp = false;
    } else if (text.rfind("  100CL", 0) == 0) {
      // Column 75: the block's format, 0 short, 1 long, 2 binary.
      const char format = text.size() >= 75 ? text[74] : '1';
      if (format == '2') Fail(path, number, "binary results are not read: write the .frd in ASCII");
      node_width = format == '0' ? 5 : 10;
    } else if (text.rfind(" -4  DISP ", 0) == 0) {  // (not DISPI, the imaginary part)
      in_disp = true;
      block = &by_step[step];
      block->clear();  // a later increment of the step replaces an earlier one
    } else if (text.rfind(" -4", 0) == 0) {
      in_disp = false;
    } else if (in_disp && text.rfind(" -1", 0) == 0) {
      const int first = 3 + node_width;
      if (static_cast<int>(text.size()) < first + 2 * 12)
        Fail(path, number, "a short displacement record");
      const long node = static_cast<long>(Field(path, number, text.substr(3, node_width)));
      std::array<double, 3> u{0.0, 0.0, 0.0};
      for (int c = 0; c < 3 && first + 12 * c < static_cast<int>(text.size()); ++c)
        u[c] = Field(path, number, text.substr(first + 12 * c, 12));
      (*block)[node] = u;
    } else if (in_disp && text.rfind(" -3", 0) == 0) {
      in_disp = false;
    }
  }
  std::vector<Displacements> steps;
  for (auto& [s, d] : by_step) steps.push_back(std::move(d));
  if (steps.empty())
    throw InputError("", path +
                             ": no displacements (DISP) in the file: ask ccx for them with "
                             "*NODE FILE and U in each step");
  return steps;
}

// .dat: the blocks "displacements (vx,vy,vz) for set ... and time ..."; those of the file's last
// time (several sets printed at one time add up; a .dat holds no step marks: one file per
// step, as one deck per load case gives).
std::vector<Displacements> ReadDat(const std::string& path, std::ifstream& in) {
  Displacements last;
  std::string last_time;
  bool any = false, in_block = false;
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (text.find("displacements (vx,vy,vz)") != std::string::npos) {
      const auto at = text.find("time");
      const std::string time = at == std::string::npos ? "" : text.substr(at);
      if (time != last_time) last.clear();
      last_time = time;
      any = in_block = true;
      continue;
    }
    if (!in_block) continue;
    std::istringstream fields(text);
    long node = 0;
    std::array<double, 3> u{0.0, 0.0, 0.0};
    if (!(fields >> node)) {
      if (!last.empty()) in_block = false;  // the blank line after the block
      continue;
    }
    std::string value;
    for (int c = 0; c < 3 && fields >> value; ++c) u[c] = Field(path, number, value);
    last[node] = u;
  }
  if (!any)
    throw InputError("", path +
                             ": no displacements in the file: ask ccx for them with "
                             "*NODE PRINT and U");
  return {last};
}

}  // namespace

std::vector<std::map<long, std::array<double, 3>>> ReadCalculixDisplacements(
    const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("", path + ": no such file");
  const std::string ext = LowerExtension(path);
  if (ext == ".frd") return ReadFrd(path, in);
  if (ext == ".dat") return ReadDat(path, in);
  throw InputError("", path + ": not a CalculiX result (expected .frd or .dat)");
}

}  // namespace springfit::io
