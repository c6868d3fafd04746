"""The laws the solver applies, shared by every grid storage: the constitutive models (stress, plastic return), the
contact between fragment fields at a node (and the layout of its statistics), and the boundary operators."""
