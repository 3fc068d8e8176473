# Run after fastddsgen (cmake -DFILES="a.cxx;b.cxx" -P PoiseIdlBoundStrings.cmake): makes the
# generated deserialisers refuse a bounded string longer than its bound.
#
# fastddsgen reads a string<N> member into a std::string and assigns it to a fixed_string<N>,
# which silently truncates: a 10,000-character e-stop reason arrived as its first 128 characters
# and was acted on. Each such assignment gets a length check first; the exception it throws is
# caught by poise::dds (components/dds/src/topics.cpp), which rejects and counts the sample.
foreach(file ${FILES})
  file(READ ${file} text)
  string(FIND "${text}" "POISE_BOUNDED_STRING_CHECK" done)
  if(NOT done EQUAL -1)
    continue()
  endif()
  string(REGEX REPLACE
    "([ \t]*)m_([A-Za-z0-9_]+) = aux\\.c_str\\(\\);"
    "\\1if (aux.size() > decltype(m_\\2)::max_size) /* POISE_BOUNDED_STRING_CHECK */\n\\1    throw eprosima::fastcdr::exception::BadParamException(\"string '\\2' is longer than its bound\");\n\\1m_\\2 = aux.c_str();"
    text "${text}")
  string(FIND "${text}" "POISE_BOUNDED_STRING_CHECK" changed)
  if(NOT changed EQUAL -1)
    string(REPLACE "#include <fastcdr/Cdr.h>"
      "#include <fastcdr/Cdr.h>\n#include <fastcdr/exceptions/BadParamException.h>" text "${text}")
  endif()
  file(WRITE ${file} "${text}")
endforeach()
