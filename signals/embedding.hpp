#pragma once
// Choosing a delay embedding before recurrence analysis: the average mutual information between x(t) and
// x(t + τ) (its first minimum is the usual delay, Fraser & Swinney), and the fraction of false nearest
// neighbours against the dimension (its drop to near zero is the usual dimension, Kennel et al.).
//
// Conventions:
//   - mutual information in nats from a 2-D histogram of equiprobable bins (each holds the same number of
//     samples, Fraser & Swinney's partition in its simplest form; the plug-in estimate, biased by about
//     (bins − 1)² / (2·pairs) nats);
//   - a neighbour j of point i in dimension D is false when, adding the coordinate x(t + D·τ), the distance
//     grows by more than `distance_ratio` times the D-dimensional distance, or the (D+1)-dimensional
//     distance exceeds `size_ratio` times the series' standard deviation; nearest neighbours by brute
//     force in the Euclidean norm, over the points that have the extra coordinate; points closer in time
//     than `theiler_window` samples are not neighbours.
#include <cstddef>
#include <vector>

namespace tirstrain::signals {

struct MutualInformationOptions {
  std::size_t bins = 16;       // histogram bins per axis
  std::size_t max_delay = 50;  // largest delay evaluated, samples
};

// mi[τ] for τ = 0 … max_delay, in nats (mi[0] is the entropy of the binned series).
std::vector<double> delayed_mutual_information(const std::vector<double>& x,
                                               const MutualInformationOptions& options);
// The first τ >= 1 where values[τ] is the smallest of values[τ − window … τ + window] (the estimate's own
// scatter makes spurious one-sample dips; window 1 is the plain first local minimum); 0 when there is none.
std::size_t first_local_minimum(const std::vector<double>& values, std::size_t window = 1);

struct FalseNeighbourOptions {
  std::size_t max_dim = 8;         // dimensions 1 … max_dim are evaluated
  std::size_t delay = 1;           // τ, samples
  double distance_ratio = 10.0;    // Kennel's R_tol
  double size_ratio = 2.0;         // Kennel's A_tol
  std::size_t theiler_window = 0;  // neighbours at least this many samples apart in time (0: only i ≠ j)
  std::size_t max_points = 20000;  // refuse longer series: the search is O(points²)
};

// fraction[D − 1] for D = 1 … max_dim: the fraction of points whose nearest neighbour is false.
std::vector<double> false_nearest_neighbours(const std::vector<double>& x,
                                             const FalseNeighbourOptions& options);

}  // namespace tirstrain::signals
