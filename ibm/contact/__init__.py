"""Contact with rigid walls and bodies: the laws (unilateral, Coulomb, Tresca) and their return maps."""
