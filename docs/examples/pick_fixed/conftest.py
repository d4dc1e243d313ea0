from hypothesis import Phase, settings

# Each example runs the engine: no deadline, and no explain phase (it re-runs failing examples
# under a line tracer, which costs the engine seconds and prints engine lines, not yours).
settings.register_profile("specs", deadline=None, phases=[p for p in Phase if p is not Phase.explain])
settings.load_profile("specs")
