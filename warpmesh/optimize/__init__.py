"""Surface optimisation and simplification on the exact surface [FG §16.4.3]: remeshing, local operators, features, size fields."""
