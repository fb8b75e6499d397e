# Classic fourth-order Runge-Kutta (runge_kutta.pyx): the stages and their combination, which the
# compiled loops call around their own right-hand side, and the cubic Hermite basis.


cpdef void rk4_stage(const double[::1] y, double h, const double[::1] k, double[::1] out) noexcept nogil
cpdef void rk4_combine(const double[::1] y, double h, const double[::1] k1, const double[::1] k2,
                       const double[::1] k3, const double[::1] k4, double[::1] out) noexcept nogil
cpdef (double, double, double, double) hermite(double theta) noexcept nogil
