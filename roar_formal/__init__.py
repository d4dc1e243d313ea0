"""roar-formal: verification toolkit for ROAR robot control architectures.

Parts: ``clf`` (the CLF engine), ``tca`` (Simmons' task-tree axioms in Z3),
``explore`` (explicit-state model checking), ``roar`` (agent specs compiled to
CLF), ``robot`` (pymunk reference robot), ``trace`` (the shared trace format).
"""

__version__ = "0.1.0"
