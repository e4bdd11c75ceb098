// Disjoint sets over 0..n-1 with path halving; each set is named by its smallest member.
#pragma once

#include <algorithm>
#include <numeric>
#include <vector>

namespace revolve::reconstruct {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  // The smallest member of x's set.
  int Find(int x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void Unite(int a, int b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

}  // namespace revolve::reconstruct
