// CalculiX / Abaqus input decks (.inp) made into a scene (mesh_import.h, proto/IMPORT.md):
// the model data (nodes, elements, sets, materials, sections, model-level boundary
// conditions) and one load case per *STEP. Keywords are read case-insensitively; a keyword
// that would change the mechanics and is not understood is an error naming its line, never
// skipped.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "engine/api/input_error.h"
#include "engine/api/scene.h"
#include "io/mesh_import.h"
#include "io/text_output.h"

namespace springfit::io {
namespace {

using proto::Json;

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::vector<std::string> SplitFields(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) out.push_back(Trim(field));
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

// One line of a deck, where it is.
struct Line {
  std::string file;
  int number = 0;
  std::string text;
  std::string where() const { return file + ":" + std::to_string(number); }
};

// A keyword line: its name (upper case) and parameters (upper-case keys, values as written),
// and the data lines up to the next keyword.
struct Card {
  Line line;
  std::string keyword;
  std::map<std::string, std::string> parameters;
  std::vector<Line> data;
  bool Has(const std::string& key) const { return parameters.count(key) > 0; }
  std::string Get(const std::string& key) const {
    const auto it = parameters.find(key);
    return it == parameters.end() ? "" : it->second;
  }
};

[[noreturn]] void Fail(const Line& line, const std::string& message) {
  throw InputError("", line.where() + ": " + message);
}

// The deck's lines, *INCLUDE files read in place (relative to the including file).
void ReadLines(const std::string& path, std::vector<Line>& lines, int depth, const Line* from) {
  if (depth > 8) Fail(*from, "*INCLUDE nested more than 8 deep");
  std::ifstream in(path);
  if (!in) {
    if (from) Fail(*from, "cannot read the included file " + path);
    throw InputError("", path + ": no such file");
  }
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const std::string t = Trim(text);
    if (t.empty() || t.rfind("**", 0) == 0) continue;  // blank or a comment
    Line line{path, number, t};
    if (Upper(t).rfind("*INCLUDE", 0) == 0) {
      std::string input;
      for (const std::string& p : SplitFields(t)) {
        const auto eq = p.find('=');
        if (eq != std::string::npos && Upper(Trim(p.substr(0, eq))) == "INPUT")
          input = Trim(p.substr(eq + 1));
      }
      if (input.empty()) Fail(line, "*INCLUDE needs INPUT=file");
      const std::filesystem::path target =
          std::filesystem::path(path).parent_path() / std::filesystem::path(input);
      ReadLines(target.string(), lines, depth + 1, &line);
      continue;
    }
    lines.push_back(std::move(line));
  }
}

std::vector<Card> Cards(const std::string& path) {
  std::vector<Line> lines;
  ReadLines(path, lines, 0, nullptr);
  std::vector<Card> cards;
  for (Line& line : lines) {
    if (line.text[0] == '*') {
      Card card;
      const std::vector<std::string> fields = SplitFields(line.text.substr(1));
      if (fields.empty() || fields[0].empty()) Fail(line, "an empty keyword");
      card.keyword = Upper(fields[0]);
      for (std::size_t i = 1; i < fields.size(); ++i) {
        if (fields[i].empty()) continue;
        const auto eq = fields[i].find('=');
        if (eq == std::string::npos) {
          card.parameters[Upper(fields[i])] = "";
        } else {
          card.parameters[Upper(Trim(fields[i].substr(0, eq)))] = Trim(fields[i].substr(eq + 1));
        }
      }
      card.line = std::move(line);
      cards.push_back(std::move(card));
    } else {
      if (cards.empty()) Fail(line, "data before the first keyword");
      // An element's line ending with a comma continues on the next (long connectivity);
      // elsewhere a trailing comma ends the line.
      std::vector<Line>& data = cards.back().data;
      if (cards.back().keyword == "ELEMENT" && !data.empty() && data.back().text.back() == ',') {
        data.back().text += line.text;
      } else {
        data.push_back(std::move(line));
      }
    }
  }
  return cards;
}

double Number(const Line& line, const std::string& text, const char* what) {
  const std::optional<double> value = NumberIn(text);
  if (!value) Fail(line, std::string("expected a number for ") + what + ", got '" + text + "'");
  return *value;
}

long Integer(const Line& line, const std::string& text, const char* what) {
  const double x = Number(line, text, what);
  if (x != std::floor(x) || std::abs(x) > 1e15)
    Fail(line, std::string("expected an integer for ") + what + ", got '" + text + "'");
  return static_cast<long>(x);
}

// What the decks describe, with the deck's own ids.
struct Deck {
  // The dimension of the mesh (SelectMeshElements): 3 with tetrahedra, 2 with triangles, the
  // trusses' otherwise.
  int dimension = 0;
  std::map<long, std::vector<double>> nodes;  // id -> x, y, z
  struct Element {
    long id = 0;
    std::vector<long> nodes;
    std::string type;
  };
  std::vector<Element> elements;
  std::map<std::string, std::vector<long>> nsets, elsets;  // upper-case names
  std::map<std::string, std::string> set_names;            // upper -> as first written
  std::vector<std::string> group_elsets;       // upper names given by *ELSET, in order (regions)
  std::map<std::string, long> element_counts;  // by type, as read (before SelectMeshElements)
  struct Material {
    std::optional<double> young, poisson;
  };
  std::map<std::string, Material> materials;
  struct Section {
    std::string elset, material;
    double thickness_or_area = 1.0;
    bool area_given = false;  // a data line was given
    Line line;
  };
  std::vector<Section> sections;
  std::string plane;  // "stress" (CPS3) or "strain" (CPE3), 2D
  bool truss = false;
  struct Step {
    std::string name;
    bool nlgeom = false;
    std::map<long, std::map<int, double>> held;  // node -> dof (0-based) -> value
    std::map<long, std::vector<double>> forces;
    struct Pressure {
      long element = 0;
      int face = 0;  // 0-based
      double value = 0.0;
      Line line;
    };
    std::vector<Pressure> pressures;
    Line line;
    std::map<long, Line> held_line;   // where each node's hold was (last) given
    std::map<long, Line> force_line;  // where each node's force was (last) given
    bool boundary_new = false;        // a *BOUNDARY, OP=NEW: the earlier holds dropped
    bool loads_new = false;           // a *CLOAD or *DLOAD, OP=NEW: the earlier loads dropped
    bool has_boundary = false, has_loads = false;
  };
  Step model;  // boundary conditions before the first step: held in every step
  std::vector<Step> steps;
};

// The ids a data field names: a node (element) id, or the name of a set.
std::vector<long> Ids(const Deck& deck, const Line& line, const std::string& field, bool nodes) {
  const auto& sets = nodes ? deck.nsets : deck.elsets;
  if (!field.empty() && (std::isdigit(static_cast<unsigned char>(field[0])) || field[0] == '-'))
    return {Integer(line, field, nodes ? "a node" : "an element")};
  const auto it = sets.find(Upper(field));
  if (it == sets.end())
    Fail(line, std::string("unknown ") + (nodes ? "node" : "element") + " set '" + field + "'");
  return it->second;
}

// Keywords that do not change a static model's mechanics: output requests, the step's
// procedure and solver controls, a density (no inertia in a static step).
const std::set<std::string> kIgnored = {
    "HEADING",  "PREPRINT",    "NODE FILE",      "EL FILE",       "NODE PRINT",
    "EL PRINT", "NODE OUTPUT", "ELEMENT OUTPUT", "OUTPUT",        "STATIC",
    "CONTROLS", "DENSITY",     "CONTACT FILE",   "CONTACT PRINT", "RESTART"};

// The parameters each keyword may carry: any other one could change what it means (an ELSET on
// *NSET, a USER load, a PERTURBATION step) and is refused.
const std::map<std::string, std::set<std::string>> kParameters = {
    {"NODE", {"NSET"}},
    {"ELEMENT", {"TYPE", "ELSET"}},
    {"NSET", {"NSET", "GENERATE"}},
    {"ELSET", {"ELSET", "GENERATE"}},
    {"MATERIAL", {"NAME"}},
    {"ELASTIC", {"TYPE"}},
    {"SOLID SECTION", {"ELSET", "MATERIAL"}},
    {"STEP", {"NAME", "NLGEOM", "INC", "INCF"}},
    {"BOUNDARY", {"OP"}},
    {"CLOAD", {"OP"}},
    {"DLOAD", {"OP"}},
};

// At most `count` non-empty fields (the rest of a line must be empty).
void ExpectFields(const Line& line, const std::vector<std::string>& f, std::size_t count,
                  const char* what) {
  for (std::size_t i = count; i < f.size(); ++i)
    if (!f[i].empty())
      Fail(line, std::string(what) + " takes " + std::to_string(count) + " fields at most");
}

// Reads one deck's cards into a Deck: one member per keyword, found through kKeywords.
class DeckReader {
 public:
  DeckReader(const std::string& path, Deck& deck) : path_(path), deck_(deck) {}

  void Read() {
    const std::vector<Card> cards = Cards(path_);
    for (const Card& card : cards) CheckParameters(card);
    for (const Card& card : cards) {
      const auto it = kKeywords.find(card.keyword);
      if (it != kKeywords.end()) {
        (this->*(it->second))(card);
      } else if (!kIgnored.count(card.keyword)) {
        Fail(card.line, "*" + card.keyword +
                            " is not read by springfit and may change the mechanics "
                            "(proto/IMPORT.md lists what is read)");
      }
    }
    if (step_) Fail(step_->line, "*STEP without *END STEP");
    CheckStepsStartFromRest();
  }

 private:
  using Handler = void (DeckReader::*)(const Card&);
  static const std::map<std::string, Handler> kKeywords;

  // Only the parameters springfit reads, each with a value it reads.
  static void CheckParameters(const Card& card) {
    const auto allowed = kParameters.find(card.keyword);
    if (allowed == kParameters.end()) return;
    for (const auto& [key, value] : card.parameters) {
      if (!allowed->second.count(key))
        Fail(card.line, "*" + card.keyword + ": parameter " + key + " is not read by springfit");
      if (key == "OP" && Upper(value) != "NEW" && Upper(value) != "MOD")
        Fail(card.line, "OP=" + value + ": expected NEW or MOD");
    }
  }

  // *NODE: the nodes, each in its set when NSET= is given.
  void Node(const Card& card) {
    if (step_) Fail(card.line, "*NODE inside a step");
    const std::string set = card.Get("NSET");
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      if (f.size() < 3) Fail(l, "a node needs an id and 2 or 3 coordinates");
      const long id = Integer(l, f[0], "a node id");
      std::vector<double> x(3, 0.0);
      for (std::size_t c = 1; c < f.size() && c <= 3; ++c)
        if (!f[c].empty()) x[c - 1] = Number(l, f[c], "a coordinate");
      if (!deck_.nodes.emplace(id, x).second)
        Fail(l, "node " + std::to_string(id) + " defined twice");
      if (!set.empty()) deck_.nsets[Upper(set)].push_back(id);
    }
    if (!set.empty()) deck_.set_names.emplace(Upper(set), set);
  }

  // *ELEMENT: elements of the types springfit reads, each in its set when ELSET= is given.
  void Element(const Card& card) {
    if (step_) Fail(card.line, "*ELEMENT inside a step");
    const std::string type = Upper(card.Get("TYPE"));
    int d = 0, count = 0;
    if (type == "CPS3" || type == "CPE3") {
      d = 2, count = 3;
      const std::string plane = type == "CPS3" ? "stress" : "strain";
      if (!deck_.plane.empty() && deck_.plane != plane)
        Fail(card.line, "CPS3 (plane stress) and CPE3 (plane strain) in one model");
      deck_.plane = plane;
    } else if (type == "C3D4") {
      d = 3, count = 4;
    } else if (type == "T2D2" || type == "T3D2") {
      d = type == "T2D2" ? 2 : 3, count = 2;
    } else {
      Fail(card.line,
           "element type '" + card.Get("TYPE") +
               "': springfit reads CPS3, CPE3 (2D triangles), C3D4 (tetrahedra) and T2D2, "
               "T3D2 (2-node trusses: an MSS reference)");
    }
    // Lower-dimensional elements beside the mesh's (Gmsh writes physical curves as T3D2
    // and a 3D mesh's boundary as CPS3) are left out later (SelectMeshElements).
    if (count > 2) deck_.dimension = std::max(deck_.dimension, d);
    const std::string set = card.Get("ELSET");
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      std::vector<std::string> ids;
      for (const std::string& s : f)
        if (!s.empty()) ids.push_back(s);
      if (static_cast<int>(ids.size()) != count + 1)
        Fail(l, type + " needs an id and " + std::to_string(count) + " nodes");
      Deck::Element e;
      e.id = Integer(l, ids[0], "an element id");
      e.type = type;
      for (int c = 1; c <= count; ++c) e.nodes.push_back(Integer(l, ids[c], "a node"));
      if (!set.empty()) deck_.elsets[Upper(set)].push_back(e.id);
      deck_.elements.push_back(std::move(e));
      ++deck_.element_counts[type];
    }
    if (!set.empty()) deck_.set_names.emplace(Upper(set), set);
  }

  // *NSET and *ELSET: a node or element set: ids, set names, or GENERATE ranges.
  void Set(const Card& card) {
    const bool nodes = card.keyword == "NSET";
    const std::string name = card.Get(nodes ? "NSET" : "ELSET");
    if (name.empty()) Fail(card.line, "*" + card.keyword + " needs " + card.keyword + "=name");
    std::vector<long>& ids = (nodes ? deck_.nsets : deck_.elsets)[Upper(name)];
    deck_.set_names.emplace(Upper(name), name);
    if (!nodes && std::find(deck_.group_elsets.begin(), deck_.group_elsets.end(), Upper(name)) ==
                      deck_.group_elsets.end())
      deck_.group_elsets.push_back(Upper(name));
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      if (card.Has("GENERATE")) {
        if (f.size() < 2) Fail(l, "GENERATE needs first, last[, step]");
        const long first = Integer(l, f[0], "first"), last = Integer(l, f[1], "last");
        const long inc = f.size() > 2 && !f[2].empty() ? Integer(l, f[2], "step") : 1;
        if (inc <= 0 || last < first || (last - first) / inc > 10000000)
          Fail(l, "GENERATE needs first <= last and a step >= 1");
        for (long id = first; id <= last; id += inc) ids.push_back(id);
      } else {
        for (const std::string& s : f)
          if (!s.empty())
            for (long id : Ids(deck_, l, s, nodes)) ids.push_back(id);
      }
    }
  }

  // *MATERIAL: a material, which the *ELASTIC after it describes.
  void Material(const Card& card) {
    material_ = Upper(card.Get("NAME"));
    if (material_.empty()) Fail(card.line, "*MATERIAL needs NAME=");
    deck_.materials[material_];
  }

  // *ELASTIC: the current material's isotropic E and nu.
  void Elastic(const Card& card) {
    if (material_.empty()) Fail(card.line, "*ELASTIC outside a *MATERIAL");
    const std::string type = Upper(card.Get("TYPE"));
    if (!type.empty() && type != "ISO")
      Fail(card.line,
           "*ELASTIC, TYPE=" + card.Get("TYPE") + ": springfit reads isotropic elasticity");
    if (card.data.empty()) Fail(card.line, "*ELASTIC needs a line: E, nu");
    const std::vector<std::string> f = SplitFields(card.data[0].text);
    if (f.size() < 2) Fail(card.data[0], "*ELASTIC needs E, nu");
    if (card.data.size() > 1 || (f.size() > 2 && !f[2].empty()))
      Fail(card.data[0], "temperature-dependent elasticity is not read");
    deck_.materials[material_].young = Number(card.data[0], f[0], "E");
    deck_.materials[material_].poisson = Number(card.data[0], f[1], "nu");
  }

  // *SOLID SECTION: an element set's material, and its thickness (2D) or area (trusses).
  void SolidSection(const Card& card) {
    Deck::Section s;
    s.elset = Upper(card.Get("ELSET"));
    s.material = Upper(card.Get("MATERIAL"));
    s.line = card.line;
    if (s.elset.empty() || s.material.empty())
      Fail(card.line, "*SOLID SECTION needs ELSET= and MATERIAL=");
    if (!card.data.empty()) {
      const std::vector<std::string> f = SplitFields(card.data[0].text);
      if (!f.empty() && !f[0].empty()) {
        s.thickness_or_area = Number(card.data[0], f[0], "the thickness or area");
        s.area_given = true;
        if (!(s.thickness_or_area > 0.0)) Fail(card.data[0], "a thickness or area must be > 0");
      }
    }
    deck_.sections.push_back(s);
  }

  // *STEP: a step opens: a load case.
  void Step(const Card& card) {
    if (step_) Fail(card.line, "*STEP inside a step (no *END STEP)");
    deck_.steps.emplace_back();
    step_ = &deck_.steps.back();
    step_->line = card.line;
    // NLGEOM, once on, stays on in the deck's later steps (as in CalculiX).
    const bool earlier = deck_.steps.size() > 1 && deck_.steps[deck_.steps.size() - 2].nlgeom;
    step_->nlgeom = card.Has("NLGEOM") ? Upper(card.Get("NLGEOM")) != "NO" : earlier;
    step_->name =
        card.Has("NAME")
            ? card.Get("NAME")
            : std::filesystem::path(path_).stem().string() +
                  (deck_.steps.size() > 1 ? " step " + std::to_string(deck_.steps.size()) : "");
  }

  // *END STEP: the step closes.
  void EndStep(const Card& card) {
    if (!step_) Fail(card.line, "*END STEP without *STEP");
    step_ = nullptr;
  }

  // *BOUNDARY: held dofs, in the open step or (before any) in every step.
  void Boundary(const Card& card) {
    Deck::Step& s = step_ ? *step_ : deck_.model;
    s.has_boundary = true;
    s.boundary_new = s.boundary_new || Upper(card.Get("OP")) == "NEW";
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      if (f.size() < 2) Fail(l, "*BOUNDARY needs node or set, first dof[, last dof[, value]]");
      ExpectFields(l, f, 4, "*BOUNDARY");
      const long first = Integer(l, f[1], "a dof");
      const long last = f.size() > 2 && !f[2].empty() ? Integer(l, f[2], "a dof") : first;
      const double value = f.size() > 3 && !f[3].empty() ? Number(l, f[3], "a value") : 0.0;
      if (first < 1 || last < first || last > 3) Fail(l, "dofs must be within 1 to 3");
      for (long node : Ids(deck_, l, f[0], true)) {
        s.held_line[node] = l;
        for (long dof = first; dof <= last; ++dof) s.held[node][static_cast<int>(dof - 1)] = value;
      }
    }
  }

  // *CLOAD: nodal forces of the open step.
  void Cload(const Card& card) {
    if (!step_) Fail(card.line, "*CLOAD outside a step");
    step_->has_loads = true;
    step_->loads_new = step_->loads_new || Upper(card.Get("OP")) == "NEW";
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      if (f.size() < 3) Fail(l, "*CLOAD needs node or set, dof, magnitude");
      ExpectFields(l, f, 3, "*CLOAD");
      const long dof = Integer(l, f[1], "a dof");
      if (dof < 1 || dof > 3) Fail(l, "*CLOAD acts on dofs 1 to 3 (a force)");
      const double value = Number(l, f[2], "a magnitude");
      for (long node : Ids(deck_, l, f[0], true)) {
        step_->force_line[node] = l;
        std::vector<double>& force = step_->forces[node];
        force.resize(3, 0.0);
        force[static_cast<std::size_t>(dof - 1)] += value;
      }
    }
  }

  // *DLOAD: pressures on tetrahedron faces in the open step.
  void Dload(const Card& card) {
    // Uniform pressure on tetrahedron faces (P1 to P4, the same labels in CalculiX and
    // Abaqus). Plane elements' edge labels differ between the two (CalculiX P3-P5 for
    // Abaqus's P1-P3), and other load types are not pressures: refused.
    if (!step_) Fail(card.line, "*DLOAD outside a step");
    step_->has_loads = true;
    step_->loads_new = step_->loads_new || Upper(card.Get("OP")) == "NEW";
    for (const Line& l : card.data) {
      const std::vector<std::string> f = SplitFields(l.text);
      if (f.size() < 3) Fail(l, "*DLOAD needs element or set, load label, magnitude");
      ExpectFields(l, f, 3, "*DLOAD");
      const std::string label = Upper(f[1]);
      if (deck_.dimension != 3 || label.size() != 2 || label[0] != 'P' || label[1] < '1' ||
          label[1] > '4') {
        Fail(l, "*DLOAD " + f[1] +
                    ": springfit reads uniform pressures P1 to P4 on C3D4 faces only; give "
                    "other distributed loads as a traction on a node set in --loads, or as "
                    "*CLOAD nodal forces");
      }
      const double value = Number(l, f[2], "a pressure");
      for (long e : Ids(deck_, l, f[0], false))
        step_->pressures.push_back({e, label[1] - '1', value, l});
    }
  }

  // CalculiX carries a step's loads and boundary conditions into the next unless OP=NEW
  // drops them; springfit's load cases each start from rest. A later step that would inherit
  // is refused rather than read differently.
  void CheckStepsStartFromRest() {
    bool loads_before = false, holds_before = false;
    for (std::size_t k = 0; k < deck_.steps.size(); ++k) {
      Deck::Step& s = deck_.steps[k];
      const std::string which = "step " + std::to_string(k + 1) + " ('" + s.name + "')";
      if (loads_before && !s.loads_new)
        Fail(s.line, which +
                         " inherits the earlier steps' loads in CalculiX; springfit's load "
                         "cases start from rest: give it *CLOAD, OP=NEW (with no lines, to "
                         "drop them), or write one deck per load case");
      if (holds_before && !s.boundary_new)
        Fail(s.line, which +
                         " inherits the earlier steps' boundary conditions in CalculiX: give "
                         "it *BOUNDARY, OP=NEW, or write one deck per load case");
      loads_before = loads_before || s.has_loads;
      holds_before = holds_before || s.has_boundary;
      // The model's boundary conditions hold in every step but one that drops them (OP=NEW).
      if (!s.boundary_new) {
        for (const auto& [node, held] : deck_.model.held) {
          for (const auto& [dof, v] : held) s.held[node].emplace(dof, v);
          s.held_line.emplace(node, deck_.model.held_line.at(node));
        }
      }
    }
  }

  const std::string& path_;
  Deck& deck_;
  Deck::Step* step_ = nullptr;  // the open step
  std::string material_;        // the current *MATERIAL's upper-case name
};

const std::map<std::string, DeckReader::Handler> DeckReader::kKeywords = {
    {"NODE", &DeckReader::Node},         {"ELEMENT", &DeckReader::Element},
    {"NSET", &DeckReader::Set},          {"MATERIAL", &DeckReader::Material},
    {"ELASTIC", &DeckReader::Elastic},   {"SOLID SECTION", &DeckReader::SolidSection},
    {"STEP", &DeckReader::Step},         {"END STEP", &DeckReader::EndStep},
    {"BOUNDARY", &DeckReader::Boundary}, {"CLOAD", &DeckReader::Cload},
    {"DLOAD", &DeckReader::Dload},       {"ELSET", &DeckReader::Set},
};

void ReadDeck(const std::string& path, Deck& deck) {
  DeckReader(path, deck).Read();
}

// The materials and sections of a deck, as text: decks of one model must agree on them.
std::string SectionsText(const Deck& deck) {
  std::ostringstream out;
  out.precision(17);
  for (const auto& [name, m] : deck.materials)
    out << name << ' ' << m.young.value_or(-1) << ' ' << m.poisson.value_or(-1) << ';';
  for (const auto& s : deck.sections)
    out << s.elset << ' ' << s.material << ' ' << s.thickness_or_area << ';';
  out << deck.plane;
  return out.str();
}

// The mesh's elements: tetrahedra where there are any, else triangles, else trusses (an MSS
// reference). Lower-dimensional elements beside them (Gmsh writes a 2D mesh's physical curves
// as T3D2 lines and a 3D mesh's boundary as CPS3) are left out with one note; every element
// set still names its elements' nodes (below). Sets `deck.dimension` and `deck.truss`.
void SelectMeshElements(Deck& deck, const std::string& path, std::vector<std::string>& notes) {
  // Sets given by *ELSET name their nodes too, as a Gmsh physical group does in a .msh, unless a
  // node set has the name: a Gmsh deck's physical groups are *ELSETs (and *NSETs only with
  // Mesh.SaveGroupsOfNodes); its elementary entities (ELSET= on *ELEMENT) are not groups.
  std::map<long, const Deck::Element*> by_id;
  for (const auto& e : deck.elements) by_id.emplace(e.id, &e);
  for (const std::string& upper : deck.group_elsets) {
    const std::vector<long>& ids = deck.elsets.at(upper);
    if (deck.nsets.count(upper)) continue;
    std::set<long> nodes;
    for (long id : ids) {
      const auto it = by_id.find(id);
      if (it != by_id.end()) nodes.insert(it->second->nodes.begin(), it->second->nodes.end());
    }
    if (!nodes.empty()) deck.nsets[upper].assign(nodes.begin(), nodes.end());
  }
  const auto count = [&](const char* type) {
    const auto it = deck.element_counts.find(type);
    return it == deck.element_counts.end() ? 0L : it->second;
  };
  std::set<std::string> kept;
  if (deck.dimension == 3) {
    kept = {"C3D4"};
  } else if (deck.dimension == 2) {
    kept = {"CPS3", "CPE3"};
  } else {
    if (count("T2D2") > 0 && count("T3D2") > 0)
      throw InputError("", path + ": T2D2 and T3D2 trusses in one model (2D and 3D)");
    deck.dimension = count("T2D2") > 0 ? 2 : 3;
    deck.truss = true;
    return;
  }
  std::string ignored;
  for (const auto& [type, n] : deck.element_counts) {
    if (kept.count(type)) continue;
    ignored += (ignored.empty() ? "" : ", ") + std::to_string(n) + " " + type;
  }
  if (ignored.empty()) return;
  std::erase_if(deck.elements, [&](const Deck::Element& e) { return !kept.count(e.type); });
  notes.push_back(path + ": " + ignored + " element(s) beside the " +
                  std::to_string(deck.elements.size()) +
                  (deck.dimension == 3 ? " tetrahedra" : " triangles") +
                  " left out (lower-dimensional: a mesher's curves or boundary faces; their "
                  "element sets still name their nodes)");
}

// Without sections, the regions `--loads` may give materials by (as a Gmsh mesh's physical
// surfaces or volumes): each element's first *ELSET, in the deck's order, made of mesh
// elements only.
void ElementRegions(const Deck& deck, DeckImport& out) {
  std::map<long, std::string> region_of;
  std::set<long> mesh;
  for (const auto& e : deck.elements) mesh.insert(e.id);
  for (const std::string& upper : deck.group_elsets) {
    const std::vector<long>& ids = deck.elsets.at(upper);
    if (ids.empty() ||
        !std::all_of(ids.begin(), ids.end(), [&](long id) { return mesh.count(id); }))
      continue;
    for (long id : ids) region_of.emplace(id, deck.set_names.at(upper));
  }
  if (region_of.empty()) return;
  for (const auto& e : deck.elements) {
    const auto it = region_of.find(e.id);
    out.element_regions.push_back(it == region_of.end() ? std::string() : it->second);
    if (it != region_of.end()) ++out.region_elements[it->second];
  }
}

// Elements a solver would reject as inverted: clockwise triangles (negative area), tetrahedra
// of negative volume by CalculiX's node order (ccx stops on a nonpositive Jacobian). springfit's
// FEM solves either orientation, so this is a note for a user who runs the deck in ccx too.
void NoteInvertedElements(const Deck& deck, const std::string& path,
                          std::vector<std::string>& notes) {
  std::vector<long> inverted;
  for (const auto& e : deck.elements) {
    if (e.nodes.size() < 3) continue;
    const auto x = [&](std::size_t k) {
      const std::vector<double>& p = deck.nodes.at(e.nodes[k]);
      return Eigen::Vector3d(p[0], p[1], p[2]);
    };
    const Eigen::Vector3d a = x(1) - x(0), b = x(2) - x(0);
    const double measure =
        e.nodes.size() == 3 ? a.x() * b.y() - a.y() * b.x() : a.cross(b).dot(x(3) - x(0));
    if (measure < 0.0) inverted.push_back(e.id);
  }
  if (inverted.empty()) return;
  std::string ids;
  for (std::size_t i = 0; i < inverted.size() && i < 8; ++i)
    ids += (i > 0 ? ", " : "") + std::to_string(inverted[i]);
  if (inverted.size() > 8) ids += ", ...";
  notes.push_back(path + ": " + std::to_string(inverted.size()) + " of " +
                  std::to_string(deck.elements.size()) + " elements are inverted (" +
                  (deck.dimension == 2 ? "clockwise" : "negative volume") + ": " + ids +
                  "); springfit solves them as they are, ccx refuses them (nonpositive "
                  "Jacobian): to run the deck in ccx, swap two nodes of each (in Gmsh, reverse "
                  "the " +
                  (deck.dimension == 2 ? "surface" : "volume") + ")");
}

// The model SceneOfAbaqusDecks builds a scene from: the first deck (the mesh, materials and
// sections every deck shares), every deck's steps in order, and the nodes the elements use,
// numbered from 0 in id order.
struct DeckModel {
  Deck first;
  std::string name;  // the first deck's path
  std::vector<Deck::Step> steps;
  std::map<long, int> index;  // deck node id -> scene node

  int NodeOf(long id, const Line& where) const {
    const auto it = index.find(id);
    if (it == index.end()) Fail(where, "node " + std::to_string(id) + ", which no element uses");
    return it->second;
  }
};

// Reads every deck: the model from the first, and the steps of all, each later deck checked to
// describe the same mesh, materials and sections.
DeckModel ReadDecks(const std::vector<std::string>& paths, DeckImport& out) {
  DeckModel model;
  model.name = paths[0];
  ReadDeck(paths[0], model.first);
  SelectMeshElements(model.first, paths[0], out.notes);
  const Deck& first = model.first;
  model.steps = first.steps;
  for (std::size_t i = 1; i < paths.size(); ++i) {
    Deck other;
    ReadDeck(paths[i], other);
    std::vector<std::string> same_notes;
    SelectMeshElements(other, paths[i], same_notes);
    if (other.nodes != first.nodes)
      throw InputError("", paths[i] + ": its nodes differ from " + paths[0] +
                               "'s (decks of one model share the mesh)");
    bool same = other.elements.size() == first.elements.size();
    for (std::size_t e = 0; same && e < other.elements.size(); ++e)
      same = other.elements[e].nodes == first.elements[e].nodes &&
             other.elements[e].type == first.elements[e].type;
    if (!same) throw InputError("", paths[i] + ": its elements differ from " + paths[0] + "'s");
    if (SectionsText(other) != SectionsText(first))
      throw InputError("", paths[i] + ": its materials or sections differ from " + paths[0] +
                               "'s (decks of one model share them)");
    model.steps.insert(model.steps.end(), other.steps.begin(), other.steps.end());
  }
  if (first.elements.empty()) throw InputError("", model.name + ": no *ELEMENT");
  return model;
}

// The nodes the elements use, in id order, numbered from 0 (their ids into out.node_ids).
void NumberNodes(DeckModel& model, DeckImport& out) {
  for (const auto& e : model.first.elements) {
    for (long n : e.nodes) {
      if (!model.first.nodes.count(n))
        throw InputError("", model.name + ": element " + std::to_string(e.id) + " uses node " +
                                 std::to_string(n) + ", which no *NODE defines");
      model.index.emplace(n, 0);
    }
  }
  int next = 0;
  for (auto& [id, i] : model.index) {
    i = next++;
    out.node_ids.push_back(id);
  }
}

Json NodesJson(const DeckModel& model) {
  const int d = model.first.dimension;
  Json nodes = Json::array();
  for (const auto& [id, i] : model.index) {
    const std::vector<double>& x = model.first.nodes.at(id);
    if (d == 2 && x[2] != 0.0)
      throw InputError("", model.name + ": node " + std::to_string(id) +
                               " has z = " + std::to_string(x[2]) +
                               " in a 2D model (CPS3, CPE3, T2D2 lie in z = 0)");
    nodes.push_back(d == 2 ? Json{x[0], x[1]} : Json{x[0], x[1], x[2]});
  }
  return nodes;
}

// Node sets by name (those whose nodes are all in the model).
Json NodeSetsJson(const DeckModel& model) {
  Json sets = Json::object();
  for (const auto& [upper, ids] : model.first.nsets) {
    std::set<int> members;
    bool whole = true;
    for (long id : ids) {
      const auto it = model.index.find(id);
      if (it == model.index.end())
        whole = false;
      else
        members.insert(it->second);
    }
    if (whole && !members.empty())
      sets[model.first.set_names.at(upper)] = std::vector<int>(members.begin(), members.end());
  }
  return sets;
}

// Each element's section (its material, and the thickness (2D) or area (trusses)), by id.
std::map<long, std::size_t> SectionOfElements(const Deck& deck) {
  std::map<long, std::size_t> section_of;
  for (std::size_t s = 0; s < deck.sections.size(); ++s) {
    const auto& sec = deck.sections[s];
    const auto set = deck.elsets.find(sec.elset);
    if (set == deck.elsets.end()) Fail(sec.line, "unknown element set '" + sec.elset + "'");
    const auto m = deck.materials.find(sec.material);
    if (m == deck.materials.end()) Fail(sec.line, "unknown material '" + sec.material + "'");
    if (!m->second.young) Fail(sec.line, "material '" + sec.material + "' has no *ELASTIC");
    for (long e : set->second) section_of[e] = s;
  }
  return section_of;
}

// 2-node trusses: an MSS reference, k = E A / L at rest.
Json TrussReference(const DeckModel& model, const std::map<long, std::size_t>& section_of) {
  const Deck& first = model.first;
  Json reference;
  reference["type"] = "mss";
  Json springs = Json::array(), stiffness = Json::array();
  for (const auto& e : first.elements) {
    if (e.type != "T2D2" && e.type != "T3D2")
      throw InputError("", model.name + ": trusses and continuum elements in one model");
    const auto s = section_of.find(e.id);
    if (s == section_of.end())
      throw InputError("", model.name + ": truss element " + std::to_string(e.id) +
                               " has no *SOLID SECTION (its area and material)");
    const auto& sec = first.sections[s->second];
    const int a = model.index.at(e.nodes[0]), b = model.index.at(e.nodes[1]);
    double l2 = 0.0;
    for (int c = 0; c < 3; ++c)
      l2 += std::pow(first.nodes.at(e.nodes[0])[c] - first.nodes.at(e.nodes[1])[c], 2);
    if (!sec.area_given)
      Fail(sec.line, "a truss section needs its cross-section area on the line after it");
    if (!(l2 > 0.0))
      throw InputError("",
                       model.name + ": truss element " + std::to_string(e.id) + " has zero length");
    springs.push_back({a, b});
    stiffness.push_back(*first.materials.at(sec.material).young * sec.thickness_or_area /
                        std::sqrt(l2));
  }
  reference["springs"] = std::move(springs);
  reference["stiffness"] = std::move(stiffness);
  return reference;
}

// Triangles or tetrahedra: an FEM reference, its materials from the sections (St. Venant-
// Kirchhoff under NLGEOM), or from --loads when the deck has no sections.
Json FemReference(const DeckModel& model, const std::map<long, std::size_t>& section_of,
                  bool nlgeom, DeckImport& out) {
  const Deck& first = model.first;
  const int d = first.dimension;
  Json reference;
  reference["type"] = "fem";
  Json elements = Json::array(), element_materials = Json::array(), materials = Json::array();
  Json element_ids = Json::array();  // which messages name elements by
  std::map<std::string, int> material_index;
  std::optional<double> thickness;
  for (const auto& e : first.elements) {
    Json nodes_of = Json::array();
    for (long n : e.nodes) nodes_of.push_back(model.index.at(n));
    elements.push_back(std::move(nodes_of));
    element_ids.push_back(e.id);
    if (!out.has_sections) continue;  // the material comes from --loads
    const auto s = section_of.find(e.id);
    if (s == section_of.end())
      throw InputError("", model.name + ": element " + std::to_string(e.id) +
                               " has no *SOLID SECTION (its material)");
    const auto& sec = first.sections[s->second];
    if (d == 2) {
      if (thickness && *thickness != sec.thickness_or_area)
        Fail(sec.line, "sections of different thickness: springfit has one thickness per model");
      thickness = sec.thickness_or_area;
    }
    auto [it, added] = material_index.emplace(sec.material, static_cast<int>(materials.size()));
    if (added) {
      const auto& m = first.materials.at(sec.material);
      materials.push_back({{"model", nlgeom ? "st_venant_kirchhoff" : "linear"},
                           {"young", *m.young},
                           {"poisson", *m.poisson}});
    }
    element_materials.push_back(it->second);
  }
  reference["elements"] = std::move(elements);
  reference["element_tags"] = std::move(element_ids);
  if (!out.has_sections) {
    ElementRegions(first, out);
  } else if (materials.size() == 1) {
    reference["material"] = materials[0];
  } else {
    reference["materials"] = std::move(materials);
    reference["element_materials"] = std::move(element_materials);
  }
  if (d == 2) {
    reference["plane"] = first.plane;
    reference["thickness"] = thickness.value_or(1.0);
  }
  return reference;
}

// A step's held nodes (every dof of the dimension, or none) into the load case's `fixed` and
// `displacements`.
void HeldNodes(const DeckModel& model, const Deck::Step& s, Json& lc) {
  const int d = model.first.dimension;
  Json fixed = Json::array(), displacements = Json::array();
  for (const auto& [node, held] : s.held) {
    const Line& where = s.held_line.at(node);
    std::vector<double> u(static_cast<std::size_t>(d), 0.0);
    int count = 0;
    for (const auto& [dof, v] : held) {
      if (dof >= d) {  // a 2D model's dof 3: holding it at 0 changes nothing
        if (v != 0.0)
          Fail(where, "node " + std::to_string(node) + ": a displacement along dof " +
                          std::to_string(dof + 1) + " in a 2D model");
        continue;
      }
      u[static_cast<std::size_t>(dof)] = v;
      ++count;
    }
    if (count == 0) continue;
    if (count != d)
      Fail(where, "node " + std::to_string(node) + " is held in " + std::to_string(count) +
                      " of its " + std::to_string(d) +
                      " directions: springfit holds a node in every direction or none");
    const int i = model.NodeOf(node, where);
    if (std::all_of(u.begin(), u.end(), [](double x) { return x == 0.0; })) {
      fixed.push_back(i);
    } else {
      displacements.push_back({{"node", i}, {"displacement", u}});
    }
  }
  lc["fixed"] = std::move(fixed);
  if (!displacements.empty()) lc["displacements"] = std::move(displacements);
}

// A step's nodal forces, its pressures added as consistent nodal forces at rest (dead loads:
// under NLGEOM CalculiX's pressure follows the face, which a dead load does not, so they are
// refused there): -p A n / 3 on each node of the face, n its outward normal; shares on held
// nodes go to the support.
void StepForces(const DeckModel& model, const Deck::Step& s, Json& lc) {
  const Deck& first = model.first;
  const int d = first.dimension;
  if (!s.pressures.empty() && s.nlgeom)
    Fail(s.pressures[0].line, "*DLOAD under NLGEOM is a follower load: not read");
  std::map<long, std::vector<double>> forces_of_step = s.forces;
  std::map<long, Line> line_of_force = s.force_line;
  std::map<long, const Deck::Element*> element_of;
  if (!s.pressures.empty())
    for (const auto& e : first.elements) element_of[e.id] = &e;
  for (const auto& p : s.pressures) {
    const auto it = element_of.find(p.element);
    if (it == element_of.end()) Fail(p.line, "unknown element " + std::to_string(p.element));
    if (it->second->type != "C3D4")
      Fail(p.line, "*DLOAD on element " + std::to_string(p.element) + " (" + it->second->type +
                       "): pressures are read on C3D4 faces only");
    // C3D4 faces: 1-2-3, 1-4-2, 2-4-3, 3-4-1 (1-based), the fourth node opposite.
    static constexpr int kFace[4][4] = {{0, 1, 2, 3}, {0, 3, 1, 2}, {1, 3, 2, 0}, {2, 3, 0, 1}};
    const auto corner = [&](int k) {
      const std::vector<double>& x = first.nodes.at(it->second->nodes[kFace[p.face][k]]);
      return Eigen::Vector3d(x[0], x[1], x[2]);
    };
    Eigen::Vector3d area = 0.5 * (corner(1) - corner(0)).cross(corner(2) - corner(0));
    if (area.dot(corner(3) - corner(0)) > 0.0) area = -area;  // outward
    for (int k = 0; k < 3; ++k) {
      const long node = it->second->nodes[kFace[p.face][k]];
      if (s.held.count(node)) continue;
      forces_of_step[node].resize(3, 0.0);
      line_of_force.emplace(node, p.line);
      std::vector<double>& force = forces_of_step[node];
      force.resize(3, 0.0);
      for (int c = 0; c < 3; ++c) force[c] -= p.value * area[c] / 3.0;
    }
  }
  Json forces = Json::array();
  for (const auto& [node, f] : forces_of_step) {
    // A force on a held node goes to the support (CalculiX counts it in the reaction).
    if (s.held.count(node)) continue;
    const int i = model.NodeOf(node, line_of_force.at(node));
    if (d == 2 && f[2] != 0.0)
      Fail(line_of_force.at(node),
           "node " + std::to_string(node) + ": a force along dof 3 in a 2D model");
    forces.push_back({{"node", i}, {"force", std::vector<double>(f.begin(), f.begin() + d)}});
  }
  if (!forces.empty()) lc["forces"] = std::move(forces);
}

}  // namespace

bool IsAbaqusDeck(const std::string& path) {
  return LowerExtension(path) == ".inp";
}

Json SceneOfAbaqusDecks(const std::vector<std::string>& paths, DeckImport* found) {
  DeckImport ignored;
  DeckImport& out = found ? *found : ignored;
  DeckModel model = ReadDecks(paths, out);
  const Deck& first = model.first;
  // A deck without steps (as Gmsh writes one) takes its load cases from --loads; one without
  // sections its material (ImportSceneFiles checks that the loads give them).
  out.has_steps = !model.steps.empty();
  out.has_sections = !first.sections.empty();
  NoteInvertedElements(first, model.name, out.notes);
  if (first.dimension == 2 && first.element_counts.count("CPS3")) {
    out.notes.push_back(
        model.name +
        ": CPS3 read as springfit's plane-stress triangle (the exact 2D law); ccx expands CPS3 "
        "into wedges, whose answers differ by about 1e-2 (5x5 plate sheared at nu 0.45); ccx's "
        "CPE3 with the plane-stress constants E(1+2nu)/(1+nu)^2 and nu/(1+nu) matches "
        "springfit's answer exactly");
  }
  NumberNodes(model, out);

  Json scene;
  scene["name"] = std::filesystem::path(model.name).stem().string();
  scene["description"] =
      "imported from " + std::filesystem::path(model.name).filename().string() +
      (paths.size() > 1 ? " and " + std::to_string(paths.size() - 1) + " more decks" : "");
  scene["nodes"] = NodesJson(model);
  scene["node_tags"] = out.node_ids;  // the deck's ids, which exports carry
  if (Json sets = NodeSetsJson(model); !sets.empty()) scene["node_sets"] = std::move(sets);

  const std::map<long, std::size_t> section_of = SectionOfElements(first);
  const bool nlgeom = !model.steps.empty() && model.steps.front().nlgeom;
  for (const auto& s : model.steps)
    if (s.nlgeom != nlgeom)
      Fail(s.line, "NLGEOM in some steps and not in others: one material law per model");
  scene["reference"] = first.truss ? TrussReference(model, section_of)
                                   : FemReference(model, section_of, nlgeom, out);

  // One load case per step.
  Json cases = Json::array();
  for (const Deck::Step& s : model.steps) {
    Json lc;
    lc["name"] = s.name;
    HeldNodes(model, s, lc);
    StepForces(model, s, lc);
    cases.push_back(std::move(lc));
  }
  if (!model.steps.empty()) scene["load_cases"] = std::move(cases);
  return scene;
}

}  // namespace springfit::io
