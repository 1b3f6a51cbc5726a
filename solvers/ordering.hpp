// The order in which a projection sweep visits the constraint list: the model's constraints
// 0..m-1 followed by the substep's contacts m..m+c-1 (solvers/options.hpp, ProjectionOrder).
//
//   Ordering ordering(model, options);           // once per model: the colouring of the model
//   ordering.set_contacts(model, contacts);      // each substep: recolours with the contacts
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
#include "solvers/options.hpp"

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

class Ordering {
 public:
  // Colours the model's constraints (for Colored); nothing else is precomputed.
  Ordering(const Model& model, const SolverOptions& options);

  ProjectionOrder order() const { return order_; }
  bool jacobi() const { return order_ == ProjectionOrder::Jacobi; }

  // The contacts of the current substep (items m..m+c-1). For Colored they are coloured on top
  // of the model's colouring (a contact conflicts with every constraint or contact that shares
  // one of its dynamic particles).
  void set_contacts(const Model& model, const std::vector<Contact>& contacts);

  // The visiting sequence of one sweep over the m + c items. Jacobi evaluates in the
  // sequential order (the order does not matter: every correction comes from the same positions).
  void sweep(long step, int substep, int sweep_index, std::vector<int>& out) const;

  // Colour of each item (model constraints then contacts) and the number of colours; empty
  // unless the order is Colored.
  const std::vector<int>& colors() const { return colors_; }
  int color_count() const;

 private:
  ProjectionOrder order_;
  std::uint64_t shuffle_seed_;
  int model_items_ = 0;
  int contact_items_ = 0;
  std::vector<std::vector<int>> model_particle_colors_;  // (n) colours of model constraints
  std::vector<int> model_colors_;                        // (m)
  std::vector<int> colors_;                              // (m + c)
  std::vector<int> colored_sequence_;                    // colour-major sequence of m + c items
};

}  // namespace pbdbench
