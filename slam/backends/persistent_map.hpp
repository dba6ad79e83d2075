#pragma once
// A persistent map from small non-negative integer keys to values, shared between copies and
// copied on write: a trie of fixed fan-out over the key's bits (balanced by construction, its
// depth the logarithm of the largest key). Copying the map copies one pointer; changing one
// entry copies only the nodes on its path that another map still shares, so a particle filter
// whose particles descend from one another shares every landmark they have not changed since
// (FastSLAM's landmark tree, docs/architecture.md "FastSLAM").
//
// Not thread-safe: all copies of one map must be used from one thread (the ownership test reads
// the shared pointers' use counts).

#include <array>
#include <cstddef>
#include <memory>
#include <unordered_set>
#include <vector>

namespace conesim::slam {

template <typename T>
class PersistentMap {
 public:
  /// Children per node: 8 (three bits of the key per level).
  static constexpr int kBits = 3;
  static constexpr int kFan = 1 << kBits;

  /// The value of `key`, null when absent.
  const T* find(int key) const {
    if (key < 0 || key >= capacity()) return nullptr;
    const Node* node = root_.get();
    for (int level = depth_; node && level > 0; --level)
      node = node->child[slot(key, level)].get();
    return node ? &node->value : nullptr;
  }

  /// The value of `key` for changing, null when absent: the nodes on its path that are shared
  /// with another map are copied first, so the other maps keep the old value.
  T* find_mut(int key) {
    if (!find(key)) return nullptr;
    Node* node = own(root_);
    for (int level = depth_; level > 0; --level) node = own(node->child[slot(key, level)]);
    return &node->value;
  }

  /// Sets `key` (>= 0) to `value`, adding it when absent.
  void set(int key, const T& value) {
    if (!find(key)) ++size_;
    while (key >= capacity()) {
      // one level more: the old tree becomes the first child of a new root
      auto root = std::make_shared<Node>();
      root->child[0] = std::move(root_);
      root_ = std::move(root);
      ++depth_;
    }
    if (!root_) root_ = std::make_shared<Node>();
    Node* node = own(root_);
    for (int level = depth_; level > 0; --level) {
      std::shared_ptr<Node>& next = node->child[slot(key, level)];
      if (!next) next = std::make_shared<Node>();
      node = own(next);
    }
    node->value = value;
  }

  /// Removes `key` (nothing when absent); nodes left empty go.
  void erase(int key) {
    if (!find(key)) return;
    erase_below(root_, key, depth_);
    --size_;
  }

  /// Entries in the map.
  int size() const { return size_; }

  /// Calls f(key, value) for every entry in key order.
  template <typename F>
  void for_each(F&& f) const {
    visit(root_.get(), depth_, 0, f);
  }

  /// Nodes reachable from all the given maps, each counted once (how much they share).
  static size_t distinct_nodes(const std::vector<const PersistentMap*>& maps) {
    std::unordered_set<const void*> seen;
    for (const PersistentMap* m : maps) count(m->root_.get(), seen);
    return seen.size();
  }

  /// Levels below the root (a key has depth() digits of kBits bits).
  int depth() const { return depth_; }

 private:
  struct Node {
    std::array<std::shared_ptr<Node>, kFan> child;
    T value{};
  };

  int capacity() const { return 1 << (kBits * depth_); }
  static int slot(int key, int level) { return (key >> (kBits * (level - 1))) & (kFan - 1); }

  // the node for writing: copied first when another map shares it
  static Node* own(std::shared_ptr<Node>& p) {
    if (p.use_count() > 1) p = std::make_shared<Node>(*p);
    return p.get();
  }

  static bool empty(const Node& n) {
    for (const auto& c : n.child)
      if (c) return false;
    return true;
  }

  // removes the key below p (p is on its path); p goes when it is left empty
  static void erase_below(std::shared_ptr<Node>& p, int key, int level) {
    if (level == 0) {
      p.reset();
      return;
    }
    Node* node = own(p);
    erase_below(node->child[slot(key, level)], key, level - 1);
    if (empty(*node)) p.reset();
  }

  template <typename F>
  static void visit(const Node* n, int level, int prefix, F& f) {
    if (!n) return;
    if (level == 0) {
      f(prefix, n->value);
      return;
    }
    for (int k = 0; k < kFan; ++k)
      if (n->child[k]) visit(n->child[k].get(), level - 1, (prefix << kBits) | k, f);
  }

  static void count(const Node* n, std::unordered_set<const void*>& seen) {
    if (!n || !seen.insert(n).second) return;
    for (const auto& c : n->child) count(c.get(), seen);
  }

  std::shared_ptr<Node> root_;
  int depth_ = 0;
  int size_ = 0;
};

}  // namespace conesim::slam
