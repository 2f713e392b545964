"""The plant file: geometry, mass, shaft, noise, what may be tracked and how far the model may be off, checked."""
