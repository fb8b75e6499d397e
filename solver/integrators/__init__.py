"""Time integration: settings, the stepper contract (base), generalised-alpha, explicit
Runge-Kutta (RK4 fixed step, RK45 / DOP853 error-controlled), the consistent start and
planar scenes."""
