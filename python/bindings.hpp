#pragma once
// What both Python modules share: C-ordered NumPy arrays and one clear line for every error.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <exception>
#include <stdexcept>
#include <string>

#include "core/error.hpp"

namespace scout::python {

template <class T>
using Array = pybind11::array_t<T, pybind11::array::c_style>;

/// Errors reach Python as one line: what the caller can fix (InputError, std::invalid_argument)
/// as ValueError, anything else (LibTorch's multi-line messages included) as RuntimeError.
inline void register_errors() {
  pybind11::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const pybind11::error_already_set&) {
      throw;
    } catch (const pybind11::builtin_exception&) {
      throw;
    } catch (const scout::InputError& e) {
      PyErr_SetString(PyExc_ValueError, scout::one_line(e.what()).c_str());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, scout::one_line(e.what()).c_str());
    } catch (const std::exception& e) {
      const std::string what = e.what();
      PyErr_SetString(PyExc_RuntimeError, scout::one_line(what.substr(0, what.find('\n'))).c_str());
    }
  });
}

}  // namespace scout::python
