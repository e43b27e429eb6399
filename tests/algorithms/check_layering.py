#!/usr/bin/env python3
"""Checks that every include in algorithms/ respects the domains' order.

The order is read from the domains' CMakeLists.txt (`ambdiag_domain(NAME
DEPENDS ...)`), the same lists the build links by. A file of domain D may
include
  - public headers of D and of the domains D depends on (transitively):
    "ambdiag/algorithms/<domain>/x.h";
  - core's public headers: "ambdiag/core/x.h";
  - from src/ only, D's private headers by bare name: "x.h" (which must
    exist in D's src/);
and no relative path ("../"), no other ambdiag module, no DDS, SQLite or
HTTP header. The compiler enforces most of this through include paths; this
check also catches relative paths and names the rule that was broken.

usage: check_layering.py ALGORITHMS_DIR      exit 1 and a line per violation
       check_layering.py --self-test         the check finds planted violations
"""
import os
import re
import sys
import tempfile

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^">]+)[">]', re.M)
DOMAIN = re.compile(r'ambdiag_domain\(\s*(\w+)(?:\s+DEPENDS\s+([\w\s]+?))?\s+SOURCES', re.S)
FORBIDDEN_SYSTEM = ('sqlite3.h', 'httplib.h', 'dds/', 'libpq', 'ddsc/')


def read_domains(root):
    deps = {}
    for name in sorted(os.listdir(root)):
        cm = os.path.join(root, name, 'CMakeLists.txt')
        if not os.path.isfile(cm):
            continue
        m = DOMAIN.search(open(cm).read())
        if not m:
            continue
        if m.group(1) != name:
            raise SystemExit(f'{cm}: domain {m.group(1)} declared in folder {name}')
        deps[name] = m.group(2).split() if m.group(2) else []
    for d, ds in deps.items():
        for x in ds:
            if x not in deps:
                raise SystemExit(f'domain {d} depends on unknown domain {x}')
    return deps


def closure(deps):
    out = {}
    def visit(d, stack):
        if d in stack:
            raise SystemExit('dependency cycle: ' + ' -> '.join(stack + [d]))
        if d not in out:
            s = set()
            for x in deps[d]:
                s |= {x} | visit(x, stack + [d])
            out[d] = s
        return out[d]
    for d in deps:
        visit(d, [])
    return out


def check(root):
    deps = read_domains(root)
    if not deps:
        return [f'{root}: no domains found']
    allowed = closure(deps)
    errors = []
    for d in deps:
        src_dir = os.path.join(root, d, 'src')
        for folder, _, files in os.walk(os.path.join(root, d)):
            public = os.sep + 'include' + os.sep in folder + os.sep
            for f in files:
                if not f.endswith(('.h', '.cc')):
                    continue
                path = os.path.join(folder, f)
                rel = os.path.relpath(path, root)
                for kind, inc in INCLUDE.findall(open(path).read()):
                    if kind == '<':
                        if inc.startswith(FORBIDDEN_SYSTEM):
                            errors.append(f'{rel}: <{inc}>: the numerics never include DDS, SQL or HTTP headers')
                        continue
                    if '..' in inc.split('/'):
                        errors.append(f'{rel}: "{inc}": relative paths step around the domains; include public headers by their ambdiag/ path')
                    elif inc.startswith('ambdiag/algorithms/'):
                        target = inc.split('/')[2]
                        if target not in deps:
                            errors.append(f'{rel}: "{inc}": no domain {target}')
                        elif target != d and target not in allowed[d]:
                            errors.append(f'{rel}: "{inc}": domain {d} may not include domain {target} '
                                          f'(it depends on: {", ".join(sorted(allowed[d])) or "nothing"})')
                    elif inc.startswith('ambdiag/'):
                        if not inc.startswith('ambdiag/core/'):
                            errors.append(f'{rel}: "{inc}": the numerics depend on core only')
                    elif '/' not in inc:
                        if public:
                            errors.append(f'{rel}: "{inc}": a public header includes a private one')
                        elif not os.path.isfile(os.path.join(src_dir, inc)):
                            errors.append(f'{rel}: "{inc}": not a private header of domain {d}')
                    else:
                        errors.append(f'{rel}: "{inc}": not an ambdiag path')
    return errors


def self_test():
    """Plants one violation of each rule in a small tree; all must be found."""
    with tempfile.TemporaryDirectory() as t:
        def write(p, text):
            os.makedirs(os.path.dirname(os.path.join(t, p)), exist_ok=True)
            open(os.path.join(t, p), 'w').write(text)
        write('low/CMakeLists.txt', 'ambdiag_domain(low\n  SOURCES\n    src/a.cc)\n')
        write('high/CMakeLists.txt', 'ambdiag_domain(high\n  DEPENDS low\n  SOURCES\n    src/b.cc)\n')
        write('low/src/a.cc', '#include "ambdiag/algorithms/high/b.h"\n#include "../../high/src/p.h"\n#include <sqlite3.h>\n')
        write('low/include/ambdiag/algorithms/low/a.h', '#include "a_private.h"\n#include "ambdiag/server/x.h"\n')
        write('high/src/b.cc', '#include "ambdiag/algorithms/low/a.h"\n#include "ambdiag/core/error.h"\n#include "p.h"\n')
        write('high/src/p.h', '')
        found = check(t)
        wanted = ['may not include domain high', 'relative paths', 'DDS, SQL or HTTP', 'public header includes a private',
                  'depend on core only']
        missing = [w for w in wanted if not any(w in e for e in found)]
        clean = [e for e in found if e.startswith('high' + os.sep)]
        if missing or clean or len(found) != len(wanted):
            print('self-test failed; found:', *found, 'missing:', *missing, 'false alarms:', *clean, sep='\n  ')
            return 1
    print('self-test: every planted violation found, none in the clean domain')
    return 0


def main():
    if sys.argv[1:] == ['--self-test']:
        return self_test()
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    errors = check(sys.argv[1])
    for e in errors:
        print(e)
    if errors:
        print(f'{len(errors)} include(s) break the layering (algorithms/CMakeLists.txt, docs/architecture.md)')
        return 1
    print(f'layering ok: {", ".join(sorted(read_domains(sys.argv[1])))}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
