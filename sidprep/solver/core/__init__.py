"""The compiled core of the solver: the FFR equations of the bodies, markers, joints and force
elements, and the integrators' steps, as Cython extension modules built by the package's build
backend (setup.py; docs/architecture.md, "The compiled code").  One module per concept, lowest
first: rotations -> records -> curves, body, constraints -> forces -> assemble -> steps, se3,
runge_kutta -> outputs, planar -> explicit, genalpha; absolute_nodal beside them."""
