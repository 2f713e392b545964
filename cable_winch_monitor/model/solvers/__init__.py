"""The equilibrium solvers: the minimum of potential (and strain) energy, one sample or many at once."""
