"""GPU building blocks shared by the methods: buffers and pools
(:mod:`.buffers`), dispatch helpers (:mod:`.dispatch`), the vertex transform
(:mod:`.transform`), scan and radix sort (:mod:`.sort`)."""
