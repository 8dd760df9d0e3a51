"""Symbolic forms of a physics: its rates and output traced by ``torch.export`` and interpreted as sympy expressions,
and the C compiler that turns printed expressions into shared libraries."""
