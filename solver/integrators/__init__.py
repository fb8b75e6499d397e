"""Time integrators shared by the solver's formulations (compiled, formulation-agnostic)."""
