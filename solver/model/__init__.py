"""Descriptions of a mechanism: bodies and markers, joints and drivers, force elements, System."""
