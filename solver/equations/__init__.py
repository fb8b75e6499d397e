"""The equations of motion, compiled: rotations, body equations, constraints, curves, force
elements, the layout of a system and its assembly (one implementation of each formula)."""
