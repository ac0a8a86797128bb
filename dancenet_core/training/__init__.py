"""Training, and nothing that generation needs: DanceNet and the comparison's models (`dancenet`), the foot
model (`footfix`), the music and motion style classifiers (`style`, `motion_style`), their settings as
dataclasses (`configs`, from which `dancenet train` builds its options) and the model cards (`cards`)."""
