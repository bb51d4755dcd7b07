"""The model: the drive as equations, with no configuration parsing and no analysis.

The bar law, the belt path geometry, the DOF map, the components (pulley inertia, springs, dampers),
the belt spans (ANCF elements on joints, or axial springs), the tensioner arms, the supports, the one
assembly path and the `System` that holds them. See docs/architecture.md.
"""
