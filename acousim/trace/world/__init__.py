"""The world the rays travel: meshes merged into one triangle set, its index, Embree, its
diffracting edges."""
