"""The training data: the Dance with Melody reader (`dance_with_melody`) and the CMU clips (`cmu_dance`), our
skeleton fitted to markers (`fit`) or retargeted from other rigs (`retarget`), the paired motion-and-music
dataset (`build`), training windows (`windows`), the song split (`split`) and a viewer of fits (`show`).
Nothing that dances imports this package."""
