#include "stratigraphy/harris_matrix.hpp"

#include "core/disjoint_sets.hpp"
#include "core/error.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <deque>
#include <numeric>

namespace strata {
namespace {

struct Word {
  const char* word;
  RelationKind kind;
  bool inverse;  // true: "A word B" means "B kind A"
};
constexpr Word kWords[] = {
    {"above", RelationKind::above, false},
    {"below", RelationKind::above, true},
    {"covers", RelationKind::above, false},
    {"covered_by", RelationKind::above, true},
    {"cuts", RelationKind::cuts, false},
    {"cut_by", RelationKind::cuts, true},
    {"fills", RelationKind::fills, false},
    {"filled_by", RelationKind::fills, true},
    {"abuts", RelationKind::abuts, false},
    {"abutted_by", RelationKind::abuts, true},
    {"same_as", RelationKind::same_as, false},
    {"equals", RelationKind::same_as, false},
    {"contemporary_with", RelationKind::contemporary_with, false},
};

}  // namespace

const char* to_string(RelationKind k) {
  switch (k) {
    case RelationKind::above: return "above";
    case RelationKind::cuts: return "cuts";
    case RelationKind::fills: return "fills";
    case RelationKind::abuts: return "abuts";
    case RelationKind::same_as: return "same_as";
    case RelationKind::contemporary_with: return "contemporary_with";
  }
  return "?";
}

std::optional<RelationKind> relation_kind_from_string(const std::string& s) {
  for (const auto& w : kWords) {
    if (!w.inverse && s == w.word) return w.kind;
  }
  return std::nullopt;
}

bool is_temporal(RelationKind k) {
  return k == RelationKind::above || k == RelationKind::cuts || k == RelationKind::fills ||
         k == RelationKind::abuts;
}

std::vector<std::string> relation_words() {
  std::vector<std::string> out;
  for (const auto& w : kWords) out.emplace_back(w.word);
  return out;
}

CanonicalRelation canonical_relation(const std::string& a, const std::string& word,
                                     const std::string& b) {
  std::string w = word;
  std::transform(w.begin(), w.end(), w.begin(), [](unsigned char c) {
    return c == '-' || c == ' ' ? '_' : char(std::tolower(c));
  });
  for (const auto& k : kWords) {
    if (w == k.word) {
      if (a == b) throw InputError(fmt::format("a unit cannot be related to itself ('{}')", a));
      return k.inverse ? CanonicalRelation{b, k.kind, a} : CanonicalRelation{a, k.kind, b};
    }
  }
  std::string known;
  for (const auto& k : kWords) known += std::string(known.empty() ? "" : ", ") + k.word;
  throw InputError(fmt::format("unknown relation '{}'; use one of: {}", word, known));
}

std::string HarrisMatrix::Node::label() const {
  std::string s;
  for (const auto& u : units) s += (s.empty() ? "" : " = ") + u;
  return s;
}

HarrisMatrix::HarrisMatrix(const std::vector<std::string>& units,
                           const std::vector<CanonicalRelation>& relations)
    : units_(units) {
  for (const auto& r : relations) add(r);
  if (relations.empty()) rebuild();
}

void HarrisMatrix::rebuild() {
  std::map<std::string, int> index;
  for (std::size_t i = 0; i < units_.size(); ++i) index[units_[i]] = int(i);
  DisjointSets<int> groups(units_.size());
  for (const auto& r : relations_) {
    if (r.kind == RelationKind::same_as) groups.unite(index.at(r.unit_a), index.at(r.unit_b));
  }
  std::map<int, int> node_of_root;
  nodes_.clear();
  node_of_unit_.clear();
  std::vector<std::string> sorted = units_;
  std::sort(sorted.begin(), sorted.end());
  for (const auto& code : sorted) {
    const int root = groups.find(index.at(code));
    auto [it, inserted] = node_of_root.try_emplace(root, int(nodes_.size()));
    if (inserted) nodes_.push_back({});
    nodes_[it->second].units.push_back(code);
    node_of_unit_[code] = it->second;
  }
  successors_.assign(nodes_.size(), {});
  for (const auto& r : relations_) {
    if (is_temporal(r.kind)) successors_[node_of_unit_.at(r.unit_a)].insert(node_of_unit_.at(r.unit_b));
  }
}

int HarrisMatrix::node_of(const std::string& unit) const {
  auto it = node_of_unit_.find(unit);
  if (it == node_of_unit_.end()) throw InputError(fmt::format("unit '{}' is not in the matrix", unit));
  return it->second;
}

std::optional<std::vector<int>> HarrisMatrix::path(int from, int to) const {
  // Breadth-first search for the shortest chain of relations.
  std::vector<int> parent(nodes_.size(), -1);
  std::deque<int> queue{from};
  parent[from] = from;
  while (!queue.empty()) {
    const int n = queue.front();
    queue.pop_front();
    if (n == to) {
      std::vector<int> p{to};
      for (int x = to; x != from; x = parent[x]) p.push_back(parent[x]);
      std::reverse(p.begin(), p.end());
      return p;
    }
    for (int s : successors_[n]) {
      if (parent[s] < 0) {
        parent[s] = n;
        queue.push_back(s);
      }
    }
  }
  return std::nullopt;
}

bool HarrisMatrix::later_than(const std::string& a, const std::string& b) const {
  const int na = node_of(a), nb = node_of(b);
  return na != nb && path(na, nb).has_value();
}

std::string HarrisMatrix::describe_cycle(const CanonicalRelation& r) const {
  // Show the chain that already exists in the opposite direction, closed by r.
  const int na = node_of(r.unit_a), nb = node_of(r.unit_b);
  std::string chain = r.unit_a + " " + to_string(r.kind) + " " + r.unit_b;
  if (na == nb) {
    return chain + ", but " + r.unit_a + " and " + r.unit_b +
           " are the same or contemporary (" + nodes_[na].label() + ")";
  }
  if (r.kind == RelationKind::same_as || r.kind == RelationKind::contemporary_with) {
    auto p = path(na, nb);
    if (!p) p = path(nb, na);
    std::string s;
    for (int n : *p) s += (s.empty() ? "" : " -> ") + nodes_[n].label();
    return chain + ", but the matrix already orders them: " + s;
  }
  auto p = path(nb, na);
  std::string s = nodes_[na].label();
  for (int n : *p) s += " -> " + nodes_[n].label();
  return "cycle " + s;
}

void HarrisMatrix::add(const CanonicalRelation& r) {
  for (const auto* code : {&r.unit_a, &r.unit_b}) {
    if (std::find(units_.begin(), units_.end(), *code) == units_.end()) {
      throw InputError(fmt::format("unit '{}' does not exist", *code));
    }
  }
  const auto saved_relations = relations_;
  if (nodes_.empty() && !units_.empty()) rebuild();
  const int na = node_of(r.unit_a), nb = node_of(r.unit_b);
  bool cycle = false;
  if (is_temporal(r.kind)) {
    cycle = na == nb || path(nb, na).has_value();
  } else if (na != nb) {
    // Joining two ordered nodes into one group (or declaring them contemporary)
    // contradicts the order.
    cycle = path(na, nb).has_value() || path(nb, na).has_value();
  }
  if (!cycle && r.kind == RelationKind::contemporary_with) {
    // Contemporary units cannot be ordered through a third unit either; checked
    // above by the two path searches.
  }
  if (cycle) {
    throw InputError(fmt::format("relation '{} {} {}' refused: it would make the Harris matrix "
                                 "contradictory: {}",
                                 r.unit_a, to_string(r.kind), r.unit_b, describe_cycle(r)));
  }
  relations_.push_back(r);
  rebuild();
  // Merging same_as groups can still join the ends of an existing path through
  // other members; verify the merged graph is acyclic and undo otherwise.
  if (r.kind == RelationKind::same_as) {
    for (std::size_t n = 0; n < nodes_.size(); ++n) {
      for (int s : successors_[n]) {
        if (int(n) == s || path(s, int(n))) {
          relations_ = saved_relations;
          rebuild();
          throw InputError(fmt::format(
              "relation '{} {} {}' refused: the merged group {} would be both above and below "
              "another unit",
              r.unit_a, to_string(r.kind), r.unit_b, nodes_[node_of(r.unit_a)].label()));
        }
      }
    }
  }
}

std::vector<std::pair<int, int>> HarrisMatrix::edges() const {
  std::vector<std::pair<int, int>> out;
  for (std::size_t n = 0; n < nodes_.size(); ++n) {
    for (int s : successors_[n]) out.emplace_back(int(n), s);
  }
  return out;
}

std::vector<std::pair<int, int>> HarrisMatrix::reduced_edges() const {
  // An edge u -> v is redundant when v is reachable from another successor of u.
  std::vector<std::pair<int, int>> out;
  for (std::size_t u = 0; u < nodes_.size(); ++u) {
    for (int v : successors_[u]) {
      bool redundant = false;
      for (int w : successors_[u]) {
        if (w != v && path(w, v)) {
          redundant = true;
          break;
        }
      }
      if (!redundant) out.emplace_back(int(u), v);
    }
  }
  return out;
}

std::vector<std::pair<int, int>> HarrisMatrix::contemporary_pairs() const {
  std::set<std::pair<int, int>> pairs;
  for (const auto& r : relations_) {
    if (r.kind != RelationKind::contemporary_with) continue;
    int a = node_of(r.unit_a), b = node_of(r.unit_b);
    pairs.emplace(std::min(a, b), std::max(a, b));
  }
  return {pairs.begin(), pairs.end()};
}

std::vector<int> HarrisMatrix::topological_order() const {
  // Kahn's algorithm, smallest label first among ready nodes for a stable order.
  std::vector<int> indegree(nodes_.size(), 0);
  for (const auto& succ : successors_) {
    for (int s : succ) ++indegree[s];
  }
  std::set<std::pair<std::string, int>> ready;
  for (std::size_t n = 0; n < nodes_.size(); ++n) {
    if (indegree[n] == 0) ready.emplace(nodes_[n].label(), int(n));
  }
  std::vector<int> order;
  while (!ready.empty()) {
    const int n = ready.begin()->second;
    ready.erase(ready.begin());
    order.push_back(n);
    for (int s : successors_[n]) {
      if (--indegree[s] == 0) ready.emplace(nodes_[s].label(), s);
    }
  }
  return order;
}

namespace {

// A DOT quoted string's content: the quote and the backslash escaped (a code may hold
// either; the door keeps control characters and line breaks out).
std::string dot_quoted(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out;
}

}  // namespace

std::string HarrisMatrix::to_dot() const {
  std::string s =
      "digraph harris_matrix {\n"
      "  rankdir=TB;\n"
      "  node [shape=box, fontname=\"Helvetica\", fontsize=11];\n"
      "  edge [arrowhead=none];\n";
  for (std::size_t n = 0; n < nodes_.size(); ++n) {
    s += fmt::format("  n{} [label=\"{}\"];\n", n, dot_quoted(nodes_[n].label()));
  }
  for (const auto& [a, b] : reduced_edges()) s += fmt::format("  n{} -> n{};\n", a, b);
  for (const auto& [a, b] : contemporary_pairs()) {
    s += fmt::format("  {{ rank=same; n{}; n{}; }}\n  n{} -> n{} [style=dashed, constraint=false];\n",
                     a, b, a, b);
  }
  s += "}\n";
  return s;
}

std::string HarrisMatrix::to_json() const {
  nlohmann::json j;
  j["nodes"] = nlohmann::json::array();
  for (const auto& n : nodes_) j["nodes"].push_back({{"id", n.units.front()}, {"units", n.units}});
  j["edges"] = nlohmann::json::array();
  for (const auto& [a, b] : reduced_edges()) {
    j["edges"].push_back({{"later", nodes_[a].units.front()}, {"earlier", nodes_[b].units.front()}});
  }
  j["contemporary"] = nlohmann::json::array();
  for (const auto& [a, b] : contemporary_pairs()) {
    j["contemporary"].push_back({nodes_[a].units.front(), nodes_[b].units.front()});
  }
  j["order"] = nlohmann::json::array();
  for (int n : topological_order()) j["order"].push_back(nodes_[n].units.front());
  return j.dump(2) + "\n";
}

}  // namespace strata
