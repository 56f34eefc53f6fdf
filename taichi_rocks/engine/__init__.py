"""The simulation on Taichi: runtime start-up, the World (fields), the pass modules (bed, flight, hashgrid,
tires) and their kernels, and Simulation, the step. The only package that writes fields."""
