"""The zone controller: applies a policy to the fleet's estimates; the factory that builds a zone from a config."""
