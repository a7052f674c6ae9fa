"""director_model: reference integrator of the rigid body in director form."""
