"""Rigid-body statics every solver shares: poses and spans, the wrench balance, the external load, one result type."""
