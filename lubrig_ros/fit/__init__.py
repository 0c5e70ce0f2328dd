"""Parameter identification from measured data (`lubrig fit`): ROS-free, on the compiled core.

Modules: `data` (a measured record from a CSV or a bag), `parameters` (the free parameters, their
units and bounds from core/schema.py), `shooting` (multiple-shooting residuals and Jacobian on
core.integrator.RigIntegrator), `solve` (bounded least squares, covariance, identifiability),
`page` (fit.json, the fitted config.yaml and the page with its figures), `defaults` (the defaults
`lubrig fit --help` shows).
"""
