"""Learning tasks: inputs → box, the evaluation r, failure, the path to follow."""
