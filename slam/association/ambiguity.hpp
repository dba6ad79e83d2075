#pragma once
// Tracking-aided association's patience (docs/architecture.md, "Association"): an observation
// whose likeliest landmark, its track's prior counted, is not clearly likelier than another one
// in its gate is not paired in this frame. Its track will be seen again, nearer and with more
// evidence; a wrong pairing, once in the map, stays there.

#include <vector>

namespace conesim::slam {

/// The observations to leave unpaired: those paired (pairing_of[i] >= 0) with a candidate whose
/// cost (d^2 + ln det S, less the track's prior) beats another gated candidate of theirs by
/// less than `margin` (2 ln of the likelihood ratio). `Pairing` has observation, candidate and
/// cost. O(pairings) with the chosen costs looked up first.
template <class Pairing>
std::vector<char> ambiguous_observations(const std::vector<Pairing>& pairings,
                                         const std::vector<int>& pairing_of, double margin) {
  std::vector<char> ambiguous(pairing_of.size(), 0);
  if (!(margin > 0.0)) return ambiguous;
  std::vector<double> chosen(pairing_of.size(), 0.0);
  for (const Pairing& p : pairings)
    if (pairing_of[p.observation] == p.candidate) chosen[p.observation] = p.cost;
  for (const Pairing& p : pairings) {
    const int j = pairing_of[p.observation];
    if (j >= 0 && j != p.candidate && p.cost - chosen[p.observation] < margin)
      ambiguous[p.observation] = 1;
  }
  return ambiguous;
}

/// 2 ln 10: the likeliest landmark must be ten times as likely as the next.
inline constexpr double kDefaultAmbiguityMargin = 4.605170185988091;

}  // namespace conesim::slam
