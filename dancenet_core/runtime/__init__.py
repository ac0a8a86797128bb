"""What a Generate Dance runs, without torch (import-linter holds this): DanceNet's sizes and settings
(`config`), the three networks in numpy (`numpy_nets`), their weights as the plain-array files generation loads
(`weights`) and the cached, compiled sampler (`sampler`). Their torch twins, for training and evaluation, are
`nets/`, which also writes these files from training checkpoints."""
