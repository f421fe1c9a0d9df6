"""The compiled pieces every engine shares: law codes, forces, steps, energies, packed layouts."""
