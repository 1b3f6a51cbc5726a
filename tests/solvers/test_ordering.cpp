// Tests of solvers/ordering.hpp: the seven projection orders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <set>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"
#include "solvers/ordering.hpp"

namespace pbdbench::test {
namespace {

bool is_permutation_of_range(std::vector<int> v, int n) {
  if (static_cast<int>(v.size()) != n) return false;
  std::sort(v.begin(), v.end());
  for (int i = 0; i < n; ++i)
    if (v[static_cast<size_t>(i)] != i) return false;
  return true;
}

// A cloth-like grid: nx * ny particles, stretch and shear distance constraints, bending between
// particles two apart, and the top row pinned.
Model grid_model(int nx, int ny) {
  Model m = empty_model(Vec3(0, -9.81, 0));
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) add_particle(m, Vec3(0.1 * i, 0.0, 0.1 * j), j == 0 ? 0.0 : 1.0);
  auto id = [nx](int i, int j) { return j * nx + i; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (i + 1 < nx) add_rest_distance(m, id(i, j), id(i + 1, j));
      if (j + 1 < ny) add_rest_distance(m, id(i, j), id(i, j + 1));
      if (i + 1 < nx && j + 1 < ny) add_rest_distance(m, id(i, j), id(i + 1, j + 1));
      if (i + 2 < nx) add_rest_distance(m, id(i, j), id(i + 2, j));
    }
  return m;
}

TEST(Ordering, ReversedIsTheReverse) {
  std::vector<int> seq = sequential_order(17);
  std::reverse(seq.begin(), seq.end());
  EXPECT_EQ(reversed_order(17), seq);
  Model m = grid_model(4, 3);
  SolverOptions o;
  o.order = ProjectionOrder::Reversed;
  Ordering ord(m, o);
  std::vector<int> out;
  ord.sweep(0, 0, 0, out);
  EXPECT_EQ(out, reversed_order(m.constraint_count()));
}

TEST(Ordering, ShuffledIsADeterministicPermutation) {
  const int n = 200;
  const std::vector<int> a = shuffled_order(n, 1, 5, 0, 2);
  EXPECT_TRUE(is_permutation_of_range(a, n));
  EXPECT_EQ(a, shuffled_order(n, 1, 5, 0, 2));  // the same seed, the same order
  EXPECT_NE(a, sequential_order(n));
  EXPECT_NE(a, shuffled_order(n, 2, 5, 0, 2));  // another seed
  EXPECT_NE(a, shuffled_order(n, 1, 6, 0, 2));  // another step
  EXPECT_NE(a, shuffled_order(n, 1, 5, 1, 2));  // another substep
  EXPECT_NE(a, shuffled_order(n, 1, 5, 0, 3));  // another sweep
  // Pinned values: std::seed_seq, std::mt19937_64 and our mapping are specified to the bit,
  // so this sequence is the same on every platform and compiler (recorded with g++ 12).
  EXPECT_EQ(shuffled_order(10, 1, 0, 0, 0), (std::vector<int>{2, 0, 9, 6, 5, 7, 3, 8, 4, 1}));
  std::mt19937_64 gen(42);
  std::vector<int> v = sequential_order(10);
  fisher_yates(v, gen);
  EXPECT_TRUE(is_permutation_of_range(v, 10));
}

TEST(Ordering, BoundedUniformIsUniform) {
  // 70000 draws in [0, 7): each count is binomial(70000, 1/7), sd = 92.6; a chi-square with 6
  // degrees of freedom above 30 has probability 4e-5 (the generator is seeded, so this is one
  // fixed sample, not a flaky test).
  std::mt19937_64 gen(3);
  std::array<int, 7> count{};
  for (int i = 0; i < 70000; ++i) {
    const std::uint64_t r = bounded_uniform(gen, 7);
    ASSERT_LT(r, 7u);
    ++count[r];
  }
  double chi2 = 0.0;
  for (int c : count) chi2 += (c - 10000.0) * (c - 10000.0) / 10000.0;
  EXPECT_LT(chi2, 30.0);
  EXPECT_EQ(bounded_uniform(gen, 1), 0u);
  // A bound close to 2^64 still works (rejects about half the draws).
  const std::uint64_t big = (std::uint64_t{1} << 63) + 12345;
  for (int i = 0; i < 100; ++i) EXPECT_LT(bounded_uniform(gen, big), big);
}

// Every colour class shares no dynamic particle, and every item appears once.
void expect_valid_coloring(const Model& m, const std::vector<Contact>& contacts,
                           const Ordering& ord) {
  const int total = m.constraint_count() + static_cast<int>(contacts.size());
  ASSERT_EQ(static_cast<int>(ord.colors().size()), total);
  std::vector<int> seq;
  ord.sweep(0, 0, 0, seq);
  EXPECT_TRUE(is_permutation_of_range(seq, total));
  // Colours appear in non-decreasing order along the sequence.
  for (size_t i = 1; i < seq.size(); ++i)
    EXPECT_LE(ord.colors()[static_cast<size_t>(seq[i - 1])],
              ord.colors()[static_cast<size_t>(seq[i])]);
  std::vector<std::set<int>> used(static_cast<size_t>(ord.color_count()));
  for (int j = 0; j < total; ++j) {
    const DynamicStencil s =
        j < m.constraint_count()
            ? dynamic_stencil(m, m.constraints[static_cast<size_t>(j)])
            : dynamic_stencil(m, contacts[static_cast<size_t>(j - m.constraint_count())]);
    auto& set = used[static_cast<size_t>(ord.colors()[static_cast<size_t>(j)])];
    for (int p : s)
      if (p >= 0) {
        EXPECT_TRUE(set.insert(p).second) << "item " << j << " particle " << p;
      }
  }
}

TEST(Ordering, ColoringIsValidAndCoversEveryConstraintOnce) {
  Model m = grid_model(6, 5);
  SolverOptions o;
  o.order = ProjectionOrder::Colored;
  Ordering ord(m, o);
  expect_valid_coloring(m, {}, ord);
  EXPECT_GT(ord.color_count(), 1);
  EXPECT_LT(ord.color_count(), 20);  // a grid needs a handful, not one per constraint

  // With contacts (planes and particle pairs): recoloured on top of the model's colours.
  m.planes.push_back({Vec3::UnitY(), 0.05, 0.0, 0.0});  // every particle below y = -0.05 + r
  m.particle_contact = true;
  Points x = m.rest_positions;
  for (int i = 0; i < m.particle_count(); ++i) x(i, 1) = -0.06 - 0.001 * i;
  x.row(20) = x.row(8);  // two particles on top of each other (not joined by a constraint)
  const std::vector<Contact> contacts = find_contacts(m, x, 0.0, 0.0);
  ASSERT_GT(contacts.size(), 10u);
  ASSERT_TRUE(std::any_of(contacts.begin(), contacts.end(),
                          [](const Contact& c) { return c.kind == ContactKind::Particle; }));
  ord.set_contacts(m, contacts, x);
  expect_valid_coloring(m, contacts, ord);
  // Back to no contacts: the model's colouring again.
  ord.set_contacts(m, {}, x);
  expect_valid_coloring(m, {}, ord);
}

TEST(Ordering, PinnedParticlesDoNotConflict) {
  // A star of constraints around one pinned particle: they share only the pinned particle, so
  // one colour holds them all.
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 0.0);
  for (int i = 0; i < 6; ++i) {
    add_particle(m, Vec3(std::cos(i), std::sin(i), 0.0), 1.0);
    add_rest_distance(m, 0, i + 1);
  }
  SolverOptions o;
  o.order = ProjectionOrder::Colored;
  Ordering ord(m, o);
  EXPECT_EQ(ord.color_count(), 1);
  // Make the centre dynamic: now every pair conflicts, six colours.
  m.inv_mass[0] = 1.0;
  m.attachments.clear();
  Ordering ord2(m, o);
  EXPECT_EQ(ord2.color_count(), 6);
}

// The dynamic stencils of the model's constraints followed by the contacts'.
std::vector<DynamicStencil> stencils_of(const Model& m, const std::vector<Contact>& contacts) {
  std::vector<DynamicStencil> s;
  for (const Constraint& c : m.constraints) s.push_back(dynamic_stencil(m, c));
  for (const Contact& c : contacts) s.push_back(dynamic_stencil(m, c));
  return s;
}

// The connected components of the items by brute force: items i and j are adjacent when their
// stencils share a particle; returns the component of each item (the smallest item in it).
std::vector<int> brute_force_components(const std::vector<DynamicStencil>& s) {
  const size_t n = s.size();
  auto adjacent = [&](size_t i, size_t j) {
    for (int p : s[i])
      for (int q : s[j])
        if (p >= 0 && p == q) return true;
    return false;
  };
  std::vector<int> comp(n, -1);
  for (size_t i = 0; i < n; ++i) {
    if (comp[i] >= 0) continue;
    comp[i] = static_cast<int>(i);
    std::vector<size_t> stack = {i};
    while (!stack.empty()) {
      const size_t a = stack.back();
      stack.pop_back();
      for (size_t b = 0; b < n; ++b)
        if (comp[b] < 0 && adjacent(a, b)) {
          comp[b] = static_cast<int>(i);
          stack.push_back(b);
        }
    }
  }
  return comp;
}

// Every group is a whole component (groups and components agree), groups come in the order of
// their smallest item, and the items of a group are ascending.
void expect_groups_are_components(const ItemGroups& g, const std::vector<DynamicStencil>& s) {
  ASSERT_EQ(g.items.size(), s.size());
  EXPECT_TRUE(is_permutation_of_range(g.items, static_cast<int>(s.size())));
  ASSERT_EQ(g.start.front(), 0);
  ASSERT_EQ(g.start.back(), static_cast<int>(s.size()));
  const std::vector<int> comp = brute_force_components(s);
  std::set<int> seen;
  int previous_smallest = -1;
  for (int k = 0; k < g.count(); ++k) {
    const int begin = g.start[static_cast<size_t>(k)], end = g.start[static_cast<size_t>(k) + 1];
    ASSERT_LT(begin, end) << "group " << k << " is empty";
    const int c = comp[static_cast<size_t>(g.items[static_cast<size_t>(begin)])];
    EXPECT_TRUE(seen.insert(c).second) << "component " << c << " split over groups";
    EXPECT_EQ(c, g.items[static_cast<size_t>(begin)]);  // its smallest item comes first
    EXPECT_GT(c, previous_smallest);                    // groups by smallest item
    previous_smallest = c;
    for (int i = begin; i < end; ++i) {
      EXPECT_EQ(comp[static_cast<size_t>(g.items[static_cast<size_t>(i)])], c);
      if (i > begin) {
        EXPECT_LT(g.items[static_cast<size_t>(i) - 1], g.items[static_cast<size_t>(i)]);
      }
    }
  }
  // Every component is some group.
  EXPECT_EQ(seen.size(), std::set<int>(comp.begin(), comp.end()).size());
}

TEST(Ordering, ItemGroupsOfAHandMadeModel) {
  // Two chains A (0-1-2-3) and B (4-5-6), particle 7 pinned and joined to 8 and to 3, particle 9
  // pinned. Constraints interleaved: c0 4-5 (B), c1 0-1 (A), c2 7-8, c3 5-6 (B), c4 1-2 (A),
  // c5 7-9 (no dynamic particle), c6 2-3 (A), c7 7-3 (A: 7 is pinned and joins nothing).
  Model m = empty_model();
  for (int i = 0; i < 10; ++i) add_particle(m, Vec3(0.1 * i, 0, 0), i == 7 || i == 9 ? 0.0 : 1.0);
  for (auto [a, b] : std::vector<std::pair<int, int>>{
           {4, 5}, {0, 1}, {7, 8}, {5, 6}, {1, 2}, {7, 9}, {2, 3}, {7, 3}})
    add_rest_distance(m, a, b);
  const ItemGroups g = item_groups(stencils_of(m, {}), m.particle_count());
  EXPECT_EQ(g.items, (std::vector<int>{0, 3, 1, 4, 6, 7, 2, 5}));
  EXPECT_EQ(g.start, (std::vector<int>{0, 2, 6, 7, 8}));
  // A particle contact between 6 (B) and 8 joins B and {c2}: item 8.
  const std::vector<Contact> contacts = {{ContactKind::Particle, 6, 8}};
  const ItemGroups h = item_groups(stencils_of(m, contacts), m.particle_count());
  EXPECT_EQ(h.items, (std::vector<int>{0, 2, 3, 8, 1, 4, 6, 7, 5}));
  EXPECT_EQ(h.start, (std::vector<int>{0, 4, 8, 9}));
  expect_groups_are_components(g, stencils_of(m, {}));
  expect_groups_are_components(h, stencils_of(m, contacts));
}

TEST(Ordering, ItemGroupsAreTheComponents) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Random rng(seed);
    Model m = random_internal_model(rng, {true, true, true, 24});
    // Pin a few particles: they join nothing.
    for (int k = 0; k < 4; ++k) m.inv_mass[static_cast<size_t>(rng.integer(0, 23))] = 0.0;
    std::vector<Contact> contacts;
    for (int k = 0; k < 5; ++k)
      contacts.push_back({ContactKind::Particle, rng.integer(0, 23), rng.integer(0, 23)});
    contacts.push_back({ContactKind::Plane, rng.integer(0, 23), 0});
    const auto s = stencils_of(m, contacts);
    SCOPED_TRACE(seed);
    expect_groups_are_components(item_groups(s, m.particle_count()), s);
  }
}

TEST(Ordering, GroupedShuffledIsDrawnOncePerStep) {
  // Two separate free grids (two groups of constraints) and a constraint between two pinned
  // particles (no dynamic particle: a group of its own).
  Model m = grid_model(6, 5);
  std::fill(m.inv_mass.begin(), m.inv_mass.end(), 1.0);
  m.attachments.clear();
  const int half = m.particle_count();
  for (int i = 0; i < half; ++i) add_particle(m, m.rest_positions.row(i).transpose() + Vec3(5, 0, 0), 1.0);
  const int first = m.constraint_count();
  for (int j = 0; j < first; ++j)
    add_rest_distance(m, m.constraints[static_cast<size_t>(j)].particles[0] + half,
                      m.constraints[static_cast<size_t>(j)].particles[1] + half);
  const int pa = add_particle(m, Vec3(9, 0, 0), 0.0), pb = add_particle(m, Vec3(9, 1, 0), 0.0);
  add_rest_distance(m, pa, pb);
  SolverOptions o;
  o.order = ProjectionOrder::GroupedShuffled;
  o.shuffle_seed = 7;
  Ordering ord(m, o);
  const int n = m.constraint_count();
  ASSERT_EQ(ord.groups().count(), 3);
  std::vector<int> a, b;
  ord.sweep(3, 0, 0, a);
  EXPECT_TRUE(is_permutation_of_range(a, n));
  // Groups are contiguous: the first grid's constraints, the second's, then the pinned one.
  for (int i = 0; i < n; ++i) {
    const int j = a[static_cast<size_t>(i)];
    const int expected_group = j == n - 1 ? 2 : (j < first ? 0 : 1);
    const int group = i < first ? 0 : (i < 2 * first ? 1 : 2);
    EXPECT_EQ(group, expected_group) << "position " << i << " item " << j;
  }
  EXPECT_NE(a, ord.groups().items);  // shuffled within the groups
  // The same permutation in every sweep and substep of the step ...
  for (int substep : {0, 1, 3})
    for (int sweep : {0, 1, 9}) {
      ord.sweep(3, substep, sweep, b);
      EXPECT_EQ(a, b) << substep << " " << sweep;
    }
  ord.set_contacts(m, {}, m.rest_positions);  // a new substep without contacts: the same
  ord.sweep(3, 1, 0, b);
  EXPECT_EQ(a, b);
  // ... another in the next step, and with another seed; the same again for the same step.
  ord.sweep(4, 0, 0, b);
  EXPECT_TRUE(is_permutation_of_range(b, n));
  EXPECT_NE(a, b);
  EXPECT_EQ(b, grouped_shuffled_order(ord.groups(), 7, 4));
  EXPECT_NE(a, grouped_shuffled_order(ord.groups(), 8, 3));
  EXPECT_EQ(a, grouped_shuffled_order(ord.groups(), 7, 3));
  // The permutation within the first group differs from the second's (independent draws).
  std::vector<int> g0(a.begin(), a.begin() + first), g1(a.begin() + first, a.begin() + 2 * first);
  for (int& j : g1) j -= first;
  EXPECT_NE(g0, g1);
}

TEST(Ordering, GroupedShuffledWithContacts) {
  // Contacts are items too: a particle contact that joins the two chains makes one group.
  Model m = chain_model(4, 0.1, 1.0, Vec3::Zero(), 1.0, 0.0, Vec3::Zero(), Vec3(1, 0, 0));
  const int p0 = m.particle_count();
  for (int i = 0; i < p0; ++i) add_particle(m, m.rest_positions.row(i).transpose() + Vec3(0, 1, 0), 1.0);
  for (int i = 0; i + 1 < p0; ++i) add_rest_distance(m, p0 + i, p0 + i + 1);
  SolverOptions o;
  o.order = ProjectionOrder::GroupedShuffled;
  Ordering ord(m, o);
  const int groups_alone = ord.groups().count();
  EXPECT_EQ(groups_alone, 2);
  const std::vector<Contact> contacts = {{ContactKind::Particle, p0 - 1, p0 + 2}};
  ord.set_contacts(m, contacts, m.rest_positions);
  EXPECT_EQ(ord.groups().count(), 1);
  std::vector<int> seq;
  ord.sweep(0, 0, 0, seq);
  EXPECT_TRUE(is_permutation_of_range(seq, m.constraint_count() + 1));
  expect_groups_are_components(ord.groups(), stencils_of(m, contacts));
}

TEST(Ordering, BottomUpSortsByTheLowestDynamicParticle) {
  // Random particles, gravity along -z (up = +z); the constraints of a random model. Each
  // item's key is the lowest z of its dynamic particles; pinned particles do not count.
  Random rng(11);
  Model m = random_internal_model(rng, {true, true, true, 16});
  m.gravity = Vec3(0, 0, -9.81);
  m.inv_mass[3] = 0.0;
  m.inv_mass[8] = 0.0;
  Points x = m.rest_positions;
  x.row(3) = Vec3(0, 0, -100).transpose();  // pinned and very low: must not pull its items down
  std::vector<Contact> contacts = {{ContactKind::Plane, 5, 0}, {ContactKind::Particle, 2, 9}};
  const auto s = stencils_of(m, contacts);
  SolverOptions o;
  o.order = ProjectionOrder::BottomUp;
  Ordering ord(m, o);
  ord.set_contacts(m, contacts, x);
  std::vector<int> seq;
  ord.sweep(0, 0, 0, seq);
  const int n = m.constraint_count() + 2;
  ASSERT_TRUE(is_permutation_of_range(seq, n));
  EXPECT_EQ(seq, bottom_up_order(s, x, Vec3::UnitZ()));
  auto key = [&](int j) {
    double h = std::numeric_limits<double>::infinity();
    for (int p : s[static_cast<size_t>(j)])
      if (p >= 0) h = std::min(h, x(p, 2));
    return h;
  };
  for (size_t i = 1; i < seq.size(); ++i) {
    const double k0 = key(seq[i - 1]), k1 = key(seq[i]);
    EXPECT_LE(k0, k1) << "position " << i;
    if (k0 == k1) {
      EXPECT_LT(seq[i - 1], seq[i]) << "ties by index";
    }
  }
  // A pinned particle's height counts for nothing: the link from a pinned particle at y = -100
  // to a free one at y = 5 comes after the link between free ones at y = 0 and 1.
  Model pins = empty_model(Vec3(0, -9.81, 0));
  add_particle(pins, Vec3(0, -100, 0), 0.0);
  add_particle(pins, Vec3(0, 5, 0), 1.0);
  add_particle(pins, Vec3(1, 0, 0), 1.0);
  add_particle(pins, Vec3(1, 1, 0), 1.0);
  add_rest_distance(pins, 0, 1);
  add_rest_distance(pins, 2, 3);
  Ordering pinned_order(pins, o);  // before set_contacts: the rest positions
  pinned_order.sweep(0, 0, 0, seq);
  EXPECT_EQ(seq, (std::vector<int>{1, 0}));
  ord.sweep(0, 0, 0, seq);
  // Ties and empty stencils, by hand: four items at heights 2, 1, 1, none, 0.
  const std::vector<DynamicStencil> hand = {
      {0, -1, -1, -1}, {1, 2, -1, -1}, {2, -1, -1, -1}, {-1, -1, -1, -1}, {3, 0, -1, -1}};
  Points y(4, 3);
  y << 0, 2, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0;
  EXPECT_EQ(bottom_up_order(hand, y, Vec3::UnitY()), (std::vector<int>{4, 1, 2, 0, 3}));
  // Another step: the same items at other heights, a new order.
  Points z = x;
  for (int i = 0; i < z.rows(); ++i) z(i, 2) = -z(i, 2);
  ord.set_contacts(m, contacts, z);
  std::vector<int> flipped;
  ord.sweep(0, 0, 0, flipped);
  EXPECT_NE(flipped, seq);
  EXPECT_EQ(flipped, bottom_up_order(s, z, Vec3::UnitZ()));
}

TEST(Ordering, BottomUpTurnsWithGravity) {
  // Rotating the positions and gravity together leaves the order unchanged (the heights are
  // the same up to round-off, and these are far from ties).
  Random rng(12);
  Model m = random_internal_model(rng, {true, false, true, 16});
  m.gravity = Vec3(0, -9.81, 0);
  const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  Model mr = m;
  mr.gravity = R * m.gravity;
  mr.rest_positions = (m.rest_positions * R.transpose()).eval();
  SolverOptions o;
  o.order = ProjectionOrder::BottomUp;
  Ordering a(m, o), b(mr, o);
  std::vector<int> sa, sb;
  a.sweep(0, 0, 0, sa);
  b.sweep(0, 0, 0, sb);
  EXPECT_EQ(sa, sb);
  EXPECT_EQ(sa, bottom_up_order(stencils_of(m, {}), m.rest_positions, Vec3::UnitY()));
  // Without gravity up is +y, fixed: the rotated scene is another order.
  mr.gravity = Vec3::Zero();
  Ordering c(mr, o);
  c.sweep(0, 0, 0, sb);
  EXPECT_NE(sa, sb);
}

// One pbd step (k = 1) with the given order from a perturbed, resting chain without gravity.
State relax_chain(const Model& m, const State& s0, ProjectionOrder order, int iterations,
                  const std::string& solver = "pbd") {
  SolverOptions o = options_for(solver, iterations);
  o.order = order;
  auto sv = make_solver(o, m);
  State s = s0;
  sv->step(m, s, 0.01);
  return s;
}

State perturbed_chain_state(const Model& m, double eps, std::uint64_t seed) {
  State s = rest_state(m);
  Random rng(seed);
  for (int i = 1; i < m.particle_count(); ++i) s.x.row(i) += eps * rng.vec(-1.0, 1.0).transpose();
  return s;
}

TEST(Ordering, AllOrdersConvergeOnAChain) {
  const Model m = chain_model(6, 0.1, 1.0, Vec3::Zero(), 1.0, 0.0, Vec3::Zero(), Vec3(1, 0, 0));
  const State s0 = perturbed_chain_state(m, 0.02, 5);
  for (const std::string solver : {"pbd", "xpbd", "pbd-seed"}) {
    for (ProjectionOrder order : all_orders()) {
      SolverOptions o = options_for(solver, 3000);
      o.order = order;
      // The listing's D3 diverges and its D2 blend leaves the constraints unsatisfied.
      if (solver == "pbd-seed") o.seed_fixes = {"D2", "D3", "D10"};
      auto sv = make_solver(o, m);
      State s = s0;
      sv->step(m, s, 0.01);
      double worst = 0.0;
      for (const Constraint& c : m.constraints)
        worst = std::max(worst, std::abs(eval_constraint(c, s.x).C));
      EXPECT_LT(worst, 1e-10) << solver << " " << to_string(order);
    }
  }
}

TEST(Ordering, JacobiApproximatesGaussSeidelForSmallCorrections) {
  // For small violations the constraints are nearly linear; Gauss-Seidel and Jacobi both
  // converge to the mass-weighted projection of the start onto the linearised
  // constraint set, so their converged results differ only by the nonlinearity, O(eps^2).
  const Model m = chain_model(5, 0.1, 1.0, Vec3::Zero(), 1.0, 0.0, Vec3::Zero(), Vec3(1, 0, 0));
  double previous = 0.0;
  for (double eps : {1e-3, 1e-4}) {
    const State s0 = perturbed_chain_state(m, eps, 9);
    const State gs = relax_chain(m, s0, ProjectionOrder::Sequential, 4000);
    const State jacobi = relax_chain(m, s0, ProjectionOrder::Jacobi, 4000);
    const double diff = max_abs_diff(gs.x, jacobi.x);
    std::printf("eps %.0e: moved %.3e, |gauss-seidel - jacobi| %.3e\n", eps,
                max_abs_diff(gs.x, s0.x), diff);
    // The positions moved by O(eps); the two orders agree to O(eps^2 / link) with a constant
    // of order one (measured 0.32 and 0.35 eps^2/link); 20 eps^2/link leaves room for it.
    EXPECT_LT(diff, 20.0 * eps * eps / 0.1) << "eps " << eps;
    EXPECT_GT(max_abs_diff(gs.x, s0.x), 0.1 * eps);  // they did move
    if (previous > 0.0) {
      EXPECT_LT(diff, 0.05 * previous);  // ~eps^2: 10x smaller eps, 100x smaller diff
    }
    previous = diff;
  }
}

}  // namespace
}  // namespace pbdbench::test
