#pragma once
// Stratigraphic relations and the Harris matrix (Harris 1979).
//
// Relations are stored in a canonical direction. The temporal ones (above, cuts,
// fills, abuts) are edges from the later unit to the earlier one; same_as joins
// units into one node; contemporary_with says two nodes must not be ordered.
// The matrix must stay a directed acyclic graph: a relation that would close a
// cycle, counting same_as/contemporary_with groups as one node, is refused.
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace strata {

enum class RelationKind { above, cuts, fills, abuts, same_as, contemporary_with };

const char* to_string(RelationKind k);
std::optional<RelationKind> relation_kind_from_string(const std::string& canonical);
bool is_temporal(RelationKind k);  // above, cuts, fills, abuts

// A relation as the user wrote it, turned into canonical form: "102 below 101" is
// "101 above 102". Throws InputError for an unknown word, listing the known ones.
struct CanonicalRelation {
  std::string unit_a;
  RelationKind kind;
  std::string unit_b;
};
CanonicalRelation canonical_relation(const std::string& a, const std::string& word,
                                     const std::string& b);
// Every word accepted on input, canonical and inverse, for --help texts.
std::vector<std::string> relation_words();

class HarrisMatrix {
 public:
  // Builds the matrix from units (codes) and canonical relations. Throws
  // InputError if the relations already contain a cycle.
  HarrisMatrix(const std::vector<std::string>& units,
               const std::vector<CanonicalRelation>& relations);

  // Throws InputError naming the cycle if adding `r` would make one (the matrix
  // is unchanged then); otherwise adds it.
  void add(const CanonicalRelation& r);

  // A node of the drawn matrix: one unit, or a same_as group.
  struct Node {
    std::vector<std::string> units;  // sorted codes; the first is the node's name
    std::string label() const;       // "101" or "101 = 105"
  };
  const std::vector<std::string>& units() const { return units_; }  // the codes given
  const std::vector<CanonicalRelation>& relations() const { return relations_; }
  const std::vector<Node>& nodes() const { return nodes_; }
  // Temporal edges (later -> earlier) between nodes, after transitive reduction:
  // only the direct relations, as a Harris matrix is drawn.
  std::vector<std::pair<int, int>> reduced_edges() const;
  // All temporal edges between nodes before reduction.
  std::vector<std::pair<int, int>> edges() const;
  // Pairs of nodes recorded as contemporary.
  std::vector<std::pair<int, int>> contemporary_pairs() const;
  // Node index of a unit code.
  int node_of(const std::string& unit) const;
  // True when unit a is (transitively) later than unit b.
  bool later_than(const std::string& a, const std::string& b) const;
  // Nodes in a topological order, latest first (top of the matrix).
  std::vector<int> topological_order() const;

  std::string to_dot() const;
  std::string to_json() const;

 private:
  void rebuild();
  // The path of relations from node `from` to node `to`, if any, as unit codes.
  std::optional<std::vector<int>> path(int from, int to) const;
  std::string describe_cycle(const CanonicalRelation& r) const;

  std::vector<std::string> units_;
  std::vector<CanonicalRelation> relations_;
  std::vector<Node> nodes_;
  std::map<std::string, int> node_of_unit_;
  std::vector<std::set<int>> successors_;  // later -> earlier
};

}  // namespace strata
