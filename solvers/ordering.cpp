#include "solvers/ordering.hpp"

#include <algorithm>
#include <limits>
#include <utility>

namespace pbdbench {

DynamicStencil dynamic_stencil(const Model& model, const Constraint& constraint) {
  DynamicStencil s{-1, -1, -1, -1};
  int k = 0;
  for (int i = 0; i < arity(constraint.kind); ++i) {
    const int p = constraint.particles[static_cast<size_t>(i)];
    if (model.inv_mass[static_cast<size_t>(p)] > 0.0) s[static_cast<size_t>(k++)] = p;
  }
  return s;
}

DynamicStencil dynamic_stencil(const Model& model, const Contact& contact) {
  DynamicStencil s{-1, -1, -1, -1};
  std::array<int, 4> ps{};
  const int count = contact_particles(model, contact, ps);
  int k = 0;
  for (int i = 0; i < count; ++i)
    if (model.inv_mass[static_cast<size_t>(ps[static_cast<size_t>(i)])] > 0.0)
      s[static_cast<size_t>(k++)] = ps[static_cast<size_t>(i)];
  return s;
}

std::vector<int> greedy_coloring(const std::vector<DynamicStencil>& items,
                                 std::vector<std::vector<int>>& particle_colors) {
  std::vector<int> colors(items.size(), 0);
  std::vector<int> used;  // colours around the current item
  for (size_t j = 0; j < items.size(); ++j) {
    used.clear();
    for (int p : items[j])
      if (p >= 0) {
        const auto& pc = particle_colors[static_cast<size_t>(p)];
        used.insert(used.end(), pc.begin(), pc.end());
      }
    std::sort(used.begin(), used.end());
    int c = 0;  // the smallest colour not in `used`
    for (int u : used) {
      if (u == c)
        ++c;
      else if (u > c)
        break;
    }
    colors[j] = c;
    for (int p : items[j])
      if (p >= 0) particle_colors[static_cast<size_t>(p)].push_back(c);
  }
  return colors;
}

std::vector<int> color_major_order(const std::vector<int>& colors) {
  int count = 0;
  for (int c : colors) count = std::max(count, c + 1);
  // Counting sort by colour; stable, so ascending index within a colour.
  std::vector<int> start(static_cast<size_t>(count) + 1, 0);
  for (int c : colors) ++start[static_cast<size_t>(c) + 1];
  for (int c = 0; c < count; ++c)
    start[static_cast<size_t>(c) + 1] += start[static_cast<size_t>(c)];
  std::vector<int> out(colors.size());
  for (size_t j = 0; j < colors.size(); ++j)
    out[static_cast<size_t>(start[static_cast<size_t>(colors[j])]++)] = static_cast<int>(j);
  return out;
}

std::vector<int> sequential_order(int n) {
  std::vector<int> out(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) out[static_cast<size_t>(i)] = i;
  return out;
}

std::vector<int> reversed_order(int n) {
  std::vector<int> out(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) out[static_cast<size_t>(i)] = n - 1 - i;
  return out;
}

std::mt19937_64 sweep_generator(std::uint64_t shuffle_seed, long step, int substep, int sweep) {
  // std::seed_seq's mixing and std::mt19937_64's seeding from it are both specified exactly by
  // the standard, so the sequence is the same on every platform.
  const auto lo = [](std::uint64_t v) { return static_cast<std::uint32_t>(v & 0xffffffffu); };
  const auto hi = [](std::uint64_t v) { return static_cast<std::uint32_t>(v >> 32); };
  const std::uint64_t st = static_cast<std::uint64_t>(step);
  std::seed_seq seq{lo(shuffle_seed),
                    hi(shuffle_seed),
                    lo(st),
                    hi(st),
                    static_cast<std::uint32_t>(substep),
                    static_cast<std::uint32_t>(sweep)};
  return std::mt19937_64(seq);
}

std::uint64_t bounded_uniform(std::mt19937_64& gen, std::uint64_t n) {
  // Accept r < 2^64 - (2^64 mod n), the largest multiple of n that fits in 64 bits; then
  // r mod n is uniform on [0, n). Everything is computed without overflow.
  const std::uint64_t max = std::numeric_limits<std::uint64_t>::max();  // 2^64 - 1
  const std::uint64_t excess = (max % n + 1) % n;                       // 2^64 mod n
  const std::uint64_t limit = max - excess;  // accept r <= limit, i.e. r < 2^64 - excess
  for (;;) {
    const std::uint64_t r = gen();
    if (r <= limit) return r % n;
  }
}

void fisher_yates(std::vector<int>& items, std::mt19937_64& gen) {
  for (size_t i = items.size(); i > 1; --i) {
    const size_t j = static_cast<size_t>(bounded_uniform(gen, i));
    std::swap(items[i - 1], items[j]);
  }
}

std::vector<int> shuffled_order(int n, std::uint64_t shuffle_seed, long step, int substep,
                                int sweep) {
  std::vector<int> out = sequential_order(n);
  std::mt19937_64 gen = sweep_generator(shuffle_seed, step, substep, sweep);
  fisher_yates(out, gen);
  return out;
}

std::mt19937_64 step_generator(std::uint64_t shuffle_seed, long step) {
  // As sweep_generator, from four words instead of six (so it never repeats a sweep's stream).
  const auto lo = [](std::uint64_t v) { return static_cast<std::uint32_t>(v & 0xffffffffu); };
  const auto hi = [](std::uint64_t v) { return static_cast<std::uint32_t>(v >> 32); };
  const std::uint64_t st = static_cast<std::uint64_t>(step);
  std::seed_seq seq{lo(shuffle_seed), hi(shuffle_seed), lo(st), hi(st)};
  return std::mt19937_64(seq);
}

namespace {

// Union-find root of particle p, with path halving.
int find_root(std::vector<int>& parent, int p) {
  while (parent[static_cast<size_t>(p)] != p) {
    parent[static_cast<size_t>(p)] = parent[static_cast<size_t>(parent[static_cast<size_t>(p)])];
    p = parent[static_cast<size_t>(p)];
  }
  return p;
}

}  // namespace

ItemGroups item_groups(const std::vector<DynamicStencil>& stencils, int particles) {
  // Particles joined by an item are in one component; an item's group is its particles' component.
  std::vector<int> parent(static_cast<size_t>(particles));
  for (int p = 0; p < particles; ++p) parent[static_cast<size_t>(p)] = p;
  for (const DynamicStencil& s : stencils) {
    if (s[0] < 0) continue;
    for (size_t i = 1; i < s.size() && s[i] >= 0; ++i) {
      const int a = find_root(parent, s[0]), b = find_root(parent, s[i]);
      if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
    }
  }
  // Group ids in the order of each group's smallest item.
  std::vector<int> group_of_root(static_cast<size_t>(particles), -1);
  std::vector<int> group(stencils.size());
  int groups = 0;
  for (size_t j = 0; j < stencils.size(); ++j) {
    if (stencils[j][0] < 0) {
      group[j] = groups++;  // moves no particle: a group of its own
      continue;
    }
    int& g = group_of_root[static_cast<size_t>(find_root(parent, stencils[j][0]))];
    if (g < 0) g = groups++;
    group[j] = g;
  }
  // Counting sort by group; stable, so ascending index within a group.
  ItemGroups out;
  out.start.assign(static_cast<size_t>(groups) + 1, 0);
  for (int g : group) ++out.start[static_cast<size_t>(g) + 1];
  for (int g = 0; g < groups; ++g)
    out.start[static_cast<size_t>(g) + 1] += out.start[static_cast<size_t>(g)];
  out.items.resize(stencils.size());
  std::vector<int> next(out.start.begin(), out.start.end() - 1);
  for (size_t j = 0; j < stencils.size(); ++j)
    out.items[static_cast<size_t>(next[static_cast<size_t>(group[j])]++)] = static_cast<int>(j);
  return out;
}

std::vector<int> grouped_shuffled_order(const ItemGroups& groups, std::uint64_t shuffle_seed,
                                        long step) {
  std::vector<int> out = groups.items;
  std::mt19937_64 gen = step_generator(shuffle_seed, step);
  for (int g = 0; g < groups.count(); ++g) {
    // Fisher-Yates on out[first, first + size), as fisher_yates.
    const size_t first = static_cast<size_t>(groups.start[static_cast<size_t>(g)]);
    const size_t size = static_cast<size_t>(groups.start[static_cast<size_t>(g) + 1]) - first;
    for (size_t i = size; i > 1; --i) {
      const size_t j = static_cast<size_t>(bounded_uniform(gen, i));
      std::swap(out[first + i - 1], out[first + j]);
    }
  }
  return out;
}

std::vector<int> bottom_up_order(const std::vector<DynamicStencil>& stencils, const Points& x,
                                 const Vec3& up) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> height(stencils.size(), inf);
  for (size_t j = 0; j < stencils.size(); ++j)
    for (int p : stencils[j])
      if (p >= 0) {
        const double y = up.dot(x.row(p).transpose());
        if (y < height[j]) height[j] = y;  // a NaN height never wins: the item sorts last
      }
  std::vector<int> out = sequential_order(static_cast<int>(stencils.size()));
  std::stable_sort(out.begin(), out.end(), [&](int a, int b) {
    return height[static_cast<size_t>(a)] < height[static_cast<size_t>(b)];
  });
  return out;
}

Ordering::Ordering(const Model& model, const SolverOptions& options)
    : order_(options.order),
      shuffle_seed_(options.shuffle_seed),
      model_items_(model.constraint_count()) {
  if (order_ == ProjectionOrder::GroupedShuffled || order_ == ProjectionOrder::BottomUp) {
    model_stencils_.reserve(model.constraints.size());
    for (const Constraint& c : model.constraints)
      model_stencils_.push_back(dynamic_stencil(model, c));
    particles_ = model.particle_count();
    up_ = up_direction(model);
    set_contacts(model, {}, model.rest_positions);  // until told otherwise: no contacts, at rest
    return;
  }
  if (order_ != ProjectionOrder::Colored) return;
  std::vector<DynamicStencil> items;
  items.reserve(model.constraints.size());
  for (const Constraint& c : model.constraints) items.push_back(dynamic_stencil(model, c));
  model_particle_colors_.assign(static_cast<size_t>(model.particle_count()), {});
  model_colors_ = greedy_coloring(items, model_particle_colors_);
  colors_ = model_colors_;
  colored_sequence_ = color_major_order(colors_);
}

void Ordering::set_contacts(const Model& model, const std::vector<Contact>& contacts,
                            const Points& x) {
  const int previous = contact_items_;
  contact_items_ = static_cast<int>(contacts.size());
  if (order_ == ProjectionOrder::GroupedShuffled || order_ == ProjectionOrder::BottomUp) {
    const bool grouped = order_ == ProjectionOrder::GroupedShuffled;
    // The model's groups stand while there are no contacts (computed once by the constructor).
    if (grouped && previous == 0 && contact_items_ == 0 && !groups_.start.empty()) return;
    stencils_ = model_stencils_;
    for (const Contact& c : contacts) stencils_.push_back(dynamic_stencil(model, c));
    if (grouped)
      groups_ = item_groups(stencils_, particles_);
    else
      bottom_up_sequence_ = bottom_up_order(stencils_, x, up_);
    return;
  }
  if (order_ != ProjectionOrder::Colored) return;
  if (previous == 0 && contact_items_ == 0) return;  // the model's colouring stands
  // Recolour: the model's colours stay, the contacts are coloured greedily around them. Only
  // the lists of the particles the contacts touch are copied and extended.
  std::vector<DynamicStencil> items;
  items.reserve(contacts.size());
  for (const Contact& c : contacts) items.push_back(dynamic_stencil(model, c));
  std::vector<int> touched;
  for (const DynamicStencil& s : items)
    for (int p : s)
      if (p >= 0) touched.push_back(p);
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  // Local particle index -> colour list, so the extension never copies all n lists.
  std::vector<std::vector<int>> local(touched.size());
  for (size_t i = 0; i < touched.size(); ++i)
    local[i] = model_particle_colors_[static_cast<size_t>(touched[i])];
  for (DynamicStencil& s : items)
    for (int& p : s)
      if (p >= 0)
        p = static_cast<int>(std::lower_bound(touched.begin(), touched.end(), p) - touched.begin());
  const std::vector<int> contact_colors = greedy_coloring(items, local);
  colors_ = model_colors_;
  colors_.insert(colors_.end(), contact_colors.begin(), contact_colors.end());
  colored_sequence_ = color_major_order(colors_);
}

void Ordering::sweep(long step, int substep, int sweep_index, std::vector<int>& out) const {
  const int n = model_items_ + contact_items_;
  switch (order_) {
    case ProjectionOrder::Sequential:
    case ProjectionOrder::Jacobi:
      out = sequential_order(n);
      return;
    case ProjectionOrder::Reversed:
      out = reversed_order(n);
      return;
    case ProjectionOrder::Shuffled:
      out = shuffled_order(n, shuffle_seed_, step, substep, sweep_index);
      return;
    case ProjectionOrder::Colored:
      out = colored_sequence_;
      return;
    case ProjectionOrder::GroupedShuffled:
      out = grouped_shuffled_order(groups_, shuffle_seed_, step);
      return;
    case ProjectionOrder::BottomUp:
      out = bottom_up_sequence_;
      return;
  }
}

int Ordering::color_count() const {
  int count = 0;
  for (int c : colors_) count = std::max(count, c + 1);
  return count;
}

}  // namespace pbdbench
