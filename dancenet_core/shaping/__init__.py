"""The steps that shape a danced motion into the dance that is written or keyed."""
