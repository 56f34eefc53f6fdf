"""The simulation on Taichi: runtime start-up, the World (fields), the pass modules (bed, flight, hashgrid,
tires), the kernels a step launches (kernels), the set-up from a Scene (setup) and Simulation, the step. The
only package that writes fields."""
