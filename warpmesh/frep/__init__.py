"""F-Rep: expressions, shapes (3D and planar), examples, the tape compiler and evaluators, code generation, pruning, Lipschitz bounds, differential geometry and projection targets."""
