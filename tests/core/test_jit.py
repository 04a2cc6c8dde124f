"""Where the compiled kernels are cached (core.jit), and a read-only install."""
import logging

from saw_ros.core import jit


def blocked(tmp_path):
    """Return a folder that cannot be made (its parent is a file), even for root."""
    (tmp_path / 'file').write_text('')
    return tmp_path / 'file' / 'folder'


def test_the_cache_goes_where_numba_cache_dir_says(tmp_path):
    folder, tried = jit.cache_folder({'NUMBA_CACHE_DIR': str(tmp_path / 'c')}, blocked(tmp_path))
    assert folder == tmp_path / 'c' and tried == [folder]


def test_a_read_only_package_caches_in_the_users_cache_folder(tmp_path):
    package = blocked(tmp_path)
    folder, tried = jit.cache_folder({'HOME': str(tmp_path / 'home')}, package)
    assert tried[0] == package / '__pycache__' / 'numba'
    assert folder == tmp_path / 'home' / '.cache' / 'saw_ros' / 'numba' and folder.is_dir()


def test_nothing_writable_compiles_in_memory_with_one_line(tmp_path, caplog):
    package = blocked(tmp_path)
    environ = {'HOME': str(package), 'XDG_CACHE_HOME': str(package / 'cache')}
    with caplog.at_level(logging.WARNING, logger='saw_ros.core'):
        assert jit.use_cache(environ, package) is False
    assert len(caplog.records) == 1
    assert 'compiling in memory' in caplog.records[0].getMessage()


def test_an_edit_of_any_kernel_module_names_a_new_cache_folder(tmp_path):
    for name in ('a.py', 'b.py', 'plain.py'):
        (tmp_path / name).write_text('import numba\n\n@numba.njit\ndef f():\n    pass\n'
                                     if name != 'plain.py' else 'x = 1\n')
    sources = list(jit.kernel_sources(tmp_path))
    assert [p.name for p in sources] == ['a.py', 'b.py']
    before = jit.digest(sources)
    (tmp_path / 'plain.py').write_text('x = 2\n')
    assert jit.digest(jit.kernel_sources(tmp_path)) == before
    (tmp_path / 'b.py').write_text((tmp_path / 'b.py').read_text() + '# edited\n')
    assert jit.digest(jit.kernel_sources(tmp_path)) != before
    # Kernels declared through core.dynamic_walls' ``compiled`` count too (core.flexure's).
    (tmp_path / 'c.py').write_text('from x import compiled\n\n@compiled\ndef f():\n    pass\n')
    assert [p.name for p in jit.kernel_sources(tmp_path)] == ['a.py', 'b.py', 'c.py']
    assert 'flexure.py' in [p.name for p in jit.kernel_sources()]
