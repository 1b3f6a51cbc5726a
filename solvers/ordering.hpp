// The order in which a projection sweep visits the constraint list: the model's constraints
// 0..m-1 followed by the substep's contacts m..m+c-1 (solver_api/options.hpp, ProjectionOrder).
//
//   Ordering ordering(model, options);           // once per model: the colouring of the model
//   ordering.set_contacts(model, contacts, x);   // each substep: recolours / regroups with the
//                                                // contacts; x: positions at the substep's start
//   ordering.sweep(step, substep, sweep, seq);   // each sweep: the visiting sequence
//
// The pieces are free functions so that each can be tested alone.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "core/contacts.hpp"
#include "core/model.hpp"
#include "core/types.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// The particles of an item of the constraint list that may move (inv_mass > 0), -1 padded.
using DynamicStencil = std::array<int, 4>;
DynamicStencil dynamic_stencil(const Model& model, const Constraint& constraint);
DynamicStencil dynamic_stencil(const Model& model, const Contact& contact);

// Greedy graph colouring: item j (in index order) gets the smallest colour not used by an
// earlier item that shares a particle of its stencil. `particle_colors` (one list per particle)
// holds the colours already used around each particle and is extended with the new items'.
// Returns the colour of each item.
std::vector<int> greedy_coloring(const std::vector<DynamicStencil>& items,
                                 std::vector<std::vector<int>>& particle_colors);

// The visiting sequence of items 0..n-1 grouped colour by colour (ascending colour, ascending
// index within a colour). `colors` has one entry per item.
std::vector<int> color_major_order(const std::vector<int>& colors);

// 0, 1, ..., n-1 and n-1, ..., 0.
std::vector<int> sequential_order(int n);
std::vector<int> reversed_order(int n);

// The Shuffled order's generator for one sweep, seeded (through std::seed_seq) from
// (shuffle_seed, step, substep, sweep), so that a run is reproducible from its options alone.
std::mt19937_64 sweep_generator(std::uint64_t shuffle_seed, long step, int substep, int sweep);

// A uniform integer in [0, n), n >= 1, by rejection on the generator's 64-bit output (portable,
// unlike std::uniform_int_distribution whose algorithm is implementation-defined).
std::uint64_t bounded_uniform(std::mt19937_64& gen, std::uint64_t n);

// Fisher-Yates shuffle of `items` in place with bounded_uniform.
void fisher_yates(std::vector<int>& items, std::mt19937_64& gen);

// A random permutation of 0..n-1 drawn for one sweep.
std::vector<int> shuffled_order(int n, std::uint64_t shuffle_seed, long step, int substep,
                                int sweep);

// The GroupedShuffled order's generator for one step, seeded (through std::seed_seq) from
// (shuffle_seed, step) alone, so that every sweep and substep of the step draws the same.
std::mt19937_64 step_generator(std::uint64_t shuffle_seed, long step);

// The items 0..n-1 split into groups: the connected components of the graph in which two items
// are adjacent when their stencils share a particle (stencils hold dynamic particles only, as
// dynamic_stencil; an item with none is a group of its own). Groups are numbered in the order of
// their smallest item; `items` lists group 0's items, then group 1's, ..., each group ascending;
// group g is items[start[g] .. start[g + 1]).
struct ItemGroups {
  std::vector<int> items;  // (n) item indices, group by group
  std::vector<int> start;  // (groups + 1) offsets into items
  int count() const { return static_cast<int>(start.size()) - 1; }
};
// `particles`: the particle count (stencil entries are in [0, particles) or -1).
ItemGroups item_groups(const std::vector<DynamicStencil>& stencils, int particles);

// The GroupedShuffled sequence: the groups in order, each group's items in a random permutation
// drawn group after group from step_generator(shuffle_seed, step).
std::vector<int> grouped_shuffled_order(const ItemGroups& groups, std::uint64_t shuffle_seed,
                                        long step);

// The BottomUp sequence: items sorted by the height up . x_p of their lowest stencil particle,
// lowest first, ties by index; items with an empty stencil last, by index. `up` is a unit vector.
std::vector<int> bottom_up_order(const std::vector<DynamicStencil>& stencils, const Points& x,
                                 const Vec3& up);

class Ordering {
 public:
  // Colours the model's constraints (for Colored), or keeps their dynamic stencils (for
  // GroupedShuffled and BottomUp); nothing else is precomputed.
  Ordering(const Model& model, const SolverOptions& options);

  ProjectionOrder order() const { return order_; }
  bool jacobi() const { return order_ == ProjectionOrder::Jacobi; }

  // The contacts of the current substep (items m..m+c-1). For Colored they are coloured on top
  // of the model's colouring (a contact conflicts with every constraint or contact that shares
  // one of its dynamic particles). For GroupedShuffled the groups of the m + c items are found
  // again; for BottomUp the m + c items are sorted by the heights of their particles in `x`,
  // the positions at the start of the substep ((n x 3) m; the other orders ignore it).
  void set_contacts(const Model& model, const std::vector<Contact>& contacts, const Points& x);

  // The visiting sequence of one sweep over the m + c items. Jacobi evaluates in the
  // sequential order (the order does not matter: every correction comes from the same positions).
  void sweep(long step, int substep, int sweep_index, std::vector<int>& out) const;

  // Colour of each item (model constraints then contacts) and the number of colours; empty
  // unless the order is Colored.
  const std::vector<int>& colors() const { return colors_; }
  int color_count() const;

  // The groups of the current m + c items; empty unless the order is GroupedShuffled.
  const ItemGroups& groups() const { return groups_; }

 private:
  ProjectionOrder order_;
  std::uint64_t shuffle_seed_;
  int model_items_ = 0;
  int contact_items_ = 0;
  std::vector<std::vector<int>> model_particle_colors_;  // (n) colours of model constraints
  std::vector<int> model_colors_;                        // (m)
  std::vector<int> colors_;                              // (m + c)
  std::vector<int> colored_sequence_;                    // colour-major sequence of m + c items
  std::vector<DynamicStencil> model_stencils_;           // (m) GroupedShuffled, BottomUp
  std::vector<DynamicStencil> stencils_;                 // (m + c) GroupedShuffled, BottomUp
  int particles_ = 0;
  Vec3 up_ = Vec3::UnitY();                              // BottomUp: up_direction(model)
  ItemGroups groups_;                                    // GroupedShuffled
  std::vector<int> bottom_up_sequence_;                  // BottomUp: sequence of m + c items
};

}  // namespace pbdbench
