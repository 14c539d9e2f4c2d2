"""Stage 3, matching: for every virtual object the tangible and pinch pair that feels most alike,
the exact search over all pairs under the perceptual cost, and the rigid transform that makes the
fingers meet; the paper's reference pose to compare with."""
