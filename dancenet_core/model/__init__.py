"""What a Generate Dance runs, without torch: DanceNet's sizes (`config`), the networks in numpy
(`numpy_nets`), the weights files generation loads (`runtime`) and the cached sampler (`sampler`). Their torch
twins, for training and evaluation, are `nets/`."""
