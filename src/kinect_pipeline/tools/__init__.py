"""The offline tools on the core: replay a bag (:mod:`.replay`), calibrate the mounting (:mod:`.calibrate`), fit
threshold curves (:mod:`.curve`), the bundled demo (:mod:`.demo`) and the nodelet under load (:mod:`.bench_ros`)."""
