# Developer loop. Every target installs what it needs into .venv first (scripts/env.sh).
.PHONY: install demo test docs bench bench-control bench-batch bench-soft generate lint clean
SH := bash

install:
	$(SH) -c 'source scripts/env.sh'

demo:
	$(SH) scripts/main.sh

test:
	$(SH) scripts/test.sh

docs:
	$(SH) -c 'source scripts/env.sh && NO_MKDOCS_2_WARNING=1 mkdocs build --strict'

bench:
	$(SH) -c 'source scripts/env.sh && python -m benchmarks.run'

bench-control:
	$(SH) -c 'source scripts/env.sh && python -m benchmarks.control'

bench-batch:
	$(SH) -c 'source scripts/env.sh && python -m benchmarks.batch'

bench-soft:
	$(SH) -c 'source scripts/env.sh && python -m benchmarks.soft_contact'

generate:
	$(SH) -c 'source scripts/env.sh && grasping-sym generate --all'

lint:
	$(SH) -c 'source scripts/env.sh && python -m pip install --quiet ruff && ruff check grasping_sym tests benchmarks examples'

clean:
	rm -rf out build site .pytest_cache
