"""Plug-ins: the contract, the registry, and one module per problem (scene → MixedVI →
results)."""
