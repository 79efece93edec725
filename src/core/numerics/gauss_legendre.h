// The 8-point Gauss–Legendre rule shared by the core's quadratures (modes.cpp's energy ledger, the frequency
// response's Fourier integrals); private to the core.
#pragma once

namespace backlash_servo
{
/// Nodes on [−1, 1]: the rule is exact for polynomials of degree ≤ 15.
constexpr double GAUSS_NODE[8] = {-0.96028985649753623168, -0.79666647741362673959, -0.52553240991632898582,
                                  -0.18343464249564980494, 0.18343464249564980494,  0.52553240991632898582,
                                  0.79666647741362673959,  0.96028985649753623168};
/// Their weights (summing to 2).
constexpr double GAUSS_WEIGHT[8] = {0.10122853629037625915, 0.22238103445337447054, 0.31370664587788728734,
                                    0.36268378337836198297, 0.36268378337836198297, 0.31370664587788728734,
                                    0.22238103445337447054, 0.10122853629037625915};
}  // namespace backlash_servo
