"""properties: invariants of every runtime module, one test module per requirement family.

Hypothesis properties, z3 obligations and cross-checks against independent references; each
test names the requirement IDs it supports with ``@pytest.mark.requirement``.
"""
